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
    /// Buffers of messages read and given back ([`Transport::recycle`]), for later messages to
    /// arrive in: a fresh buffer for each message was zeroed first, and a master zeroed as many
    /// bytes a frame as the frame has pixel bytes.
    spare: RefCell<Vec<Vec<u8>>>,
    /// Receives poll without napping ([`Transport::set_spinning`]).
    spinning: std::cell::Cell<bool>,
    /// Every rank runs on this rank's machine ([`Transport::shares_memory`]).
    one_machine: bool,
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

/// Buffers given back are kept for later messages (at most this many, of at most this many bytes
/// together): those of at least `SPARE_BUFFER_MIN_BYTES` (a smaller message is zeroed at little
/// cost) and at most `SPARE_BUFFER_MAX_BYTES` (a mesh or a texture file now and then is not worth
/// holding on to).
const SPARE_BUFFERS_KEPT: usize = 16;
const SPARE_BYTES_KEPT: usize = 64 << 20;
const SPARE_BUFFER_MIN_BYTES: usize = 4 << 10;
const SPARE_BUFFER_MAX_BYTES: usize = 16 << 20;

impl MpiTransport {
    /// Initialises MPI (once per process) and installs the panic hook that ends the job.
    pub fn init() -> Result<MpiTransport, TransportError> {
        let (universe, _threading) = mpi::initialize_with_threading(mpi::Threading::Funneled)
            .ok_or_else(|| TransportError("MPI was initialised already".into()))?;
        precise_naps();
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        // Every rank calls this at start-up (a collective): the ranks that share this one's
        // memory, all of them when the job runs on one machine.
        let one_machine = world.split_shared(world.rank()).size() == world.size();
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
            spare: RefCell::new(Vec::new()),
            spinning: std::cell::Cell::new(false),
            one_machine,
            _universe: universe,
        })
    }

    /// Starts receiving every message that has been announced, each into its own buffer.
    fn match_announced(&self) {
        let mut receiving = self.receiving.borrow_mut();
        while let Some((message, status)) = self.world.any_process().immediate_matched_probe() {
            let length = usize::try_from(status.count(u8::equivalent_datatype())).unwrap_or(0);
            let bytes = RawBuffer::from(self.buffer_for(length));
            // SAFETY: the buffer is taken back only once the request has completed
            // (`take_received`, or `drop`), and nothing else refers to it meanwhile.
            let request = message.immediate_matched_receive_into(StaticScope, unsafe { bytes.slice() });
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
        // SAFETY: the receive into `r.bytes` has completed; its buffer is taken back once.
        Some((r.from, unsafe { r.bytes.into_vec() }))
    }

    /// A buffer of `length` bytes for a message to arrive in: a spare one where one is long
    /// enough (the shortest such), else a new one.
    fn buffer_for(&self, length: usize) -> Vec<u8> {
        let mut spare = self.spare.borrow_mut();
        let fitting = spare.iter().enumerate().filter(|(_, b)| b.len() >= length).min_by_key(|(_, b)| b.len());
        match fitting {
            Some((k, _)) if length >= SPARE_BUFFER_MIN_BYTES => {
                let mut buffer = spare.swap_remove(k);
                buffer.truncate(length);
                buffer
            }
            _ => vec![0u8; length],
        }
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
                // SAFETY: the send has completed.
                Ok(_) => drop(unsafe { s.bytes.into_vec() }),
                Err(request) => still.push(Sending { request, bytes: s.bytes }),
            }
        }
        *sending = still;
    }
}

/// A send under way, and the bytes it reads: taken apart for the request's `'static` scope, and
/// freed once the request has completed.
struct Sending {
    request: Request<'static, [u8], StaticScope>,
    bytes: RawBuffer,
}

/// A message being received: its sender, whether it has all arrived, and the buffer it arrives
/// in (owned here; the request writes to it until it completes).
struct Receiving {
    from: usize,
    state: Received,
    bytes: RawBuffer,
}

/// A `Vec<u8>` taken apart while a send reads or a receive writes its bytes, so that nothing
/// holds it (or a reference to its bytes) that MPI's use of them would alias.
struct RawBuffer {
    ptr: *mut u8,
    len: usize,
    capacity: usize,
}

impl From<Vec<u8>> for RawBuffer {
    fn from(v: Vec<u8>) -> RawBuffer {
        let mut v = std::mem::ManuallyDrop::new(v);
        RawBuffer { ptr: v.as_mut_ptr(), len: v.len(), capacity: v.capacity() }
    }
}

impl RawBuffer {
    /// The bytes, for a send to read or a receive to write into.
    ///
    /// # Safety
    /// The buffer must outlive every use of the slice: it is put together again only once the
    /// receive has completed.
    unsafe fn slice(&self) -> &'static mut [u8] {
        // SAFETY: `ptr` and `len` are a live `Vec<u8>`'s, whose bytes are initialised.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }
    }

    /// The `Vec<u8>` again.
    ///
    /// # Safety
    /// Once, after the send or the receive has completed.
    unsafe fn into_vec(self) -> Vec<u8> {
        // SAFETY: the parts of a `Vec<u8>` taken apart once (`from`).
        unsafe { Vec::from_raw_parts(self.ptr, self.len, self.capacity) }
    }
}

enum Received {
    Arriving(Request<'static, [u8], StaticScope>),
    Whole,
}

impl Drop for MpiTransport {
    fn drop(&mut self) {
        // Before MPI is finalised (the universe is the last field dropped).
        for s in self.sending.get_mut().drain(..) {
            s.request.wait();
            // SAFETY: the send has completed.
            drop(unsafe { s.bytes.into_vec() });
        }
        for r in self.receiving.get_mut().drain(..) {
            if let Received::Arriving(request) = r.state {
                request.wait();
            }
            // SAFETY: the receive has completed.
            drop(unsafe { r.bytes.into_vec() });
        }
    }
}

/// Makes this thread's naps last about as long as asked. Linux lets a sleep run late by the
/// thread's timer slack (50 us unless set), which would double each of the transport's 50 us
/// naps; a worker's fetch waits through several of them for an answer the master makes in a
/// fraction of that time.
fn precise_naps() {
    #[cfg(target_os = "linux")]
    // SAFETY: PR_SET_TIMERSLACK takes the slack in nanoseconds and changes only this thread.
    unsafe {
        libc::prctl(libc::PR_SET_TIMERSLACK, 1_000 as libc::c_ulong);
    }
}

impl Transport for MpiTransport {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn send(&self, to: usize, bytes: Vec<u8>) -> Result<(), TransportError> {
        if to >= self.size {
            return Err(TransportError(format!("there is no rank {to} in a job of {}", self.size)));
        }
        self.progress();
        let bytes = RawBuffer::from(bytes);
        // SAFETY: the buffer is put together again only once the send has completed (`progress`,
        // or `drop`), and nothing else refers to it meanwhile.
        let request = self.world.process_at_rank(to as i32).immediate_send(StaticScope, &*unsafe { bytes.slice() });
        self.sending.borrow_mut().push(Sending { request, bytes });
        Ok(())
    }

    fn recv(&self) -> Result<(usize, Vec<u8>), TransportError> {
        let start = Instant::now();
        loop {
            if let Some(m) = self.try_recv()? {
                return Ok(m);
            }
            if self.spinning.get() || start.elapsed() < SPIN {
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

    fn set_spinning(&self, spinning: bool) {
        self.spinning.set(spinning);
    }

    fn shares_memory(&self) -> bool {
        self.one_machine
    }

    fn try_recv(&self) -> Result<Option<(usize, Vec<u8>)>, TransportError> {
        self.progress();
        self.match_announced();
        Ok(self.take_received())
    }

    fn recycle(&self, bytes: Vec<u8>) {
        if bytes.len() < SPARE_BUFFER_MIN_BYTES || bytes.capacity() > SPARE_BUFFER_MAX_BYTES {
            return;
        }
        let mut spare = self.spare.borrow_mut();
        spare.push(bytes);
        let held = |spare: &[Vec<u8>]| spare.iter().map(Vec::capacity).sum::<usize>();
        while spare.len() > SPARE_BUFFERS_KEPT || held(&spare) > SPARE_BYTES_KEPT {
            // The shortest goes: the longer ones take more messages.
            let Some((k, _)) = spare.iter().enumerate().min_by_key(|(_, b)| b.len()) else { break };
            spare.swap_remove(k);
        }
    }
}
