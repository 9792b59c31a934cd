//! The MPI transport (rsmpi over the system's MPI, Open MPI on Debian): the ranks of an `mpirun`
//! job, every message a byte string on the world communicator.
//!
//! Only the thread that made the transport calls MPI (`MPI_THREAD_FUNNELED`); rendering threads
//! never do. Receives poll without blocking and sleep between polls once nothing has come for a
//! while: a blocking MPI receive spins its core, which a worker on the same node would miss.
//!
//! Open MPI has no fault tolerance: a rank that dies ends the job (mpirun reports which rank).
//! A rank that panics calls `MPI_Abort` after the panic message, so the job ends with the rank
//! named instead of its peers waiting for it.

use super::transport::{Transport, TransportError};
use mpi::point_to_point::{Destination, MatchedReceiveVec, Source};
use mpi::topology::{Communicator, SimpleCommunicator};
use std::time::{Duration, Instant};

/// This process's place in an `mpirun` job. MPI is finalised when it is dropped.
pub struct MpiTransport {
    world: SimpleCommunicator,
    rank: usize,
    size: usize,
    // Declared last: MPI is finalised after everything above is gone.
    _universe: mpi::environment::Universe,
}

/// How long a receive polls flat out before it starts sleeping between polls, and how long it
/// then sleeps: short enough for a tile's round trip, long enough to leave the core to rendering
/// (a master that spun while its workers shared its cores slowed them by a third).
const SPIN: Duration = Duration::from_micros(0);
const NAP: Duration = Duration::from_micros(50);

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
        Ok(MpiTransport { world, rank, size, _universe: universe })
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
        self.world.process_at_rank(to as i32).send(bytes);
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
            } else {
                std::thread::sleep(NAP);
            }
        }
    }

    fn try_recv(&self) -> Result<Option<(usize, Vec<u8>)>, TransportError> {
        Ok(self.world.any_process().immediate_matched_probe().map(|matched| {
            let (bytes, status) = matched.matched_receive_vec::<u8>();
            (status.source_rank() as usize, bytes)
        }))
    }
}
