//! The MPI transport (rsmpi over the system's MPI, Open MPI on Debian): the ranks of an `mpirun`
//! job, every message a byte string on the world communicator.
//!
//! Only the thread that made the transport calls MPI (`MPI_THREAD_FUNNELED`); rendering threads
//! never do. Sends are immediate (`MPI_Isend`): a large message goes out by rendezvous, which
//! waits for the receiver, and a blocking send from each side of a pair at once would deadlock.
//! The transport owns each message's bytes until its send completes, and completes sends as it
//! is called (and all of them before MPI is finalised). Receives are immediate too: a message is
//! matched as soon as it is announced and its bytes arrive while this rank goes on with others,
//! so a sender slow to move its large message along (its talking thread waiting for a core)
//! holds up only its own messages, never the master's answers to every other worker. Receives
//! poll without blocking and sleep between polls once nothing has come for a while: a blocking
//! MPI receive spins its core, which a worker on the same node would miss.
//!
//! Open MPI has no fault tolerance: a rank that dies ends the job (mpirun reports which rank).
//! A rank that panics calls `MPI_Abort` after the panic message, so the job ends with the rank
//! named instead of its peers waiting for it.

use super::transport::{Transport, TransportError};
use mpi::datatype::Equivalence;
use mpi::point_to_point::{Destination, Source};
use mpi::request::{Request, StaticScope};
use mpi::topology::{Communicator, SimpleCommunicator};
use std::cell::RefCell;
use std::time::{Duration, Instant};

/// This process's place in an `mpirun` job. MPI is finalised when it is dropped.
pub struct MpiTransport {
    world: SimpleCommunicator,
    rank: usize,
    size: usize,
    /// Sends under way.
    sending: RefCell<Vec<Sending>>,
    /// Messages matched and being received, in the order they were matched.
    receiving: RefCell<Vec<Receiving>>,
    // Declared last: MPI is finalised after everything above is gone.
    _universe: mpi::environment::Universe,
}

/// How long a receive polls flat out before it starts sleeping between polls, and how long it
/// then sleeps: short enough for a tile's round trip, long enough to leave the core to rendering
/// (a master that spun while its workers shared its cores slowed them by a third).
const SPIN: Duration = Duration::from_micros(0);
const NAP: Duration = Duration::from_micros(50);
/// While sends are under way, how long a receive keeps polling (yielding the core in between)
/// before it naps: a peer may be waiting for this side to move a large send along.
const SPIN_WHILE_SENDING: Duration = Duration::from_micros(50);

impl MpiTransport {
    /// Initialises MPI (once per process) and installs the panic hook that ends the job.
    pub fn init() -> Result<MpiTransport, TransportError> {
        let (universe, _threading) = mpi::initialize_with_threading(mpi::Threading::Funneled)
            .ok_or_else(|| TransportError("MPI was initialised already".into()))?;
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            previous(info);
            eprintln!("error: rank {rank} of {size} failed; ending the MPI job");
            SimpleCommunicator::world().abort(101);
        }));
        Ok(MpiTransport {
            world,
            rank,
            size,
            sending: RefCell::new(Vec::new()),
            receiving: RefCell::new(Vec::new()),
            _universe: universe,
        })
    }

    /// Starts receiving every message that has been announced, each into its own buffer.
    fn match_announced(&self) {
        let mut receiving = self.receiving.borrow_mut();
        while let Some((message, status)) = self.world.any_process().immediate_matched_probe() {
            let length = usize::try_from(status.count(u8::equivalent_datatype())).unwrap_or(0);
            let bytes: *mut [u8] = Box::into_raw(vec![0u8; length].into_boxed_slice());
            // SAFETY: `bytes` is freed only once the request has completed (`take_received`,
            // or `drop`), and nothing else refers to it meanwhile.
            let request = message.immediate_matched_receive_into(StaticScope, unsafe { &mut *bytes });
            let from = status.source_rank() as usize;
            receiving.push(Receiving { from, state: Received::Arriving(request), bytes });
        }
    }

    /// The first whole message of a sender none of whose earlier messages is still arriving.
    fn take_received(&self) -> Option<(usize, Vec<u8>)> {
        let mut receiving = self.receiving.borrow_mut();
        let mut waiting_for: Vec<usize> = Vec::new();
        let mut found = None;
        for (k, r) in receiving.iter_mut().enumerate() {
            if let Received::Arriving(request) = std::mem::replace(&mut r.state, Received::Whole) {
                if let Err(request) = request.test() {
                    r.state = Received::Arriving(request);
                }
            }
            match r.state {
                Received::Arriving(_) => waiting_for.push(r.from),
                Received::Whole if !waiting_for.contains(&r.from) => {
                    found = Some(k);
                    break;
                }
                Received::Whole => {}
            }
        }
        let r = receiving.remove(found?);
        // SAFETY: the receive into `r.bytes` has completed; its box is taken back once.
        let bytes = unsafe { Box::from_raw(r.bytes) };
        Some((r.from, bytes.into_vec()))
    }

    /// Whether messages are moving either way.
    fn moving(&self) -> bool {
        !self.sending.borrow().is_empty() || !self.receiving.borrow().is_empty()
    }

    /// Completes the sends that have finished, freeing their bytes.
    fn progress(&self) {
        let mut sending = self.sending.borrow_mut();
        let mut still = Vec::with_capacity(sending.len());
        for s in sending.drain(..) {
            match s.request.test() {
                Ok(_) => free(s.bytes),
                Err(request) => still.push(Sending { request, bytes: s.bytes }),
            }
        }
        *sending = still;
    }
}

/// A send under way, and the bytes it reads: leaked for the request's `'static` scope, and
/// freed once the request has completed.
struct Sending {
    request: Request<'static, [u8], StaticScope>,
    bytes: &'static [u8],
}

/// A message being received: its sender, whether it has all arrived, and the buffer it arrives
/// in (owned here; the request writes to it until it completes).
struct Receiving {
    from: usize,
    state: Received,
    bytes: *mut [u8],
}

enum Received {
    Arriving(Request<'static, [u8], StaticScope>),
    Whole,
}

fn free(bytes: &'static [u8]) {
    // SAFETY: `bytes` came from `Box::leak` in `send`, its request has completed, and nothing
    // else refers to it.
    drop(unsafe { Box::from_raw(bytes as *const [u8] as *mut [u8]) });
}

impl Drop for MpiTransport {
    fn drop(&mut self) {
        // Before MPI is finalised (the universe is the last field dropped).
        for s in self.sending.get_mut().drain(..) {
            s.request.wait();
            free(s.bytes);
        }
        for r in self.receiving.get_mut().drain(..) {
            if let Received::Arriving(request) = r.state {
                request.wait();
            }
            // SAFETY: the receive has completed.
            drop(unsafe { Box::from_raw(r.bytes) });
        }
    }
}

impl Transport for MpiTransport {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn send(&self, to: usize, bytes: &[u8]) -> Result<(), TransportError> {
        if to >= self.size {
            return Err(TransportError(format!("there is no rank {to} in a job of {}", self.size)));
        }
        self.progress();
        let bytes: &'static [u8] = Box::leak(bytes.to_vec().into_boxed_slice());
        let request = self.world.process_at_rank(to as i32).immediate_send(StaticScope, bytes);
        self.sending.borrow_mut().push(Sending { request, bytes });
        Ok(())
    }

    fn recv(&self) -> Result<(usize, Vec<u8>), TransportError> {
        let start = Instant::now();
        loop {
            if let Some(m) = self.try_recv()? {
                return Ok(m);
            }
            if start.elapsed() < SPIN {
                std::hint::spin_loop();
            } else if self.moving() && start.elapsed() < SPIN_WHILE_SENDING {
                // A peer may be waiting for this side to move a send along, or a message on its
                // way in moves as this side calls MPI.
                std::thread::yield_now();
            } else {
                std::thread::sleep(NAP);
            }
        }
    }

    fn sending(&self) -> bool {
        self.progress();
        self.moving()
    }

    fn try_recv(&self) -> Result<Option<(usize, Vec<u8>)>, TransportError> {
        self.progress();
        self.match_announced();
        Ok(self.take_received())
    }
}
