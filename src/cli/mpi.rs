//! `--mpi`: the subcommands that render over the ranks of an `mpirun` job. Rank 0 is the master
//! (it loads the scene, prints and writes what a single process would); every other rank loads
//! the same scene quietly and serves the master as a worker (`rtsl_runtime::distributed`).

use rtsl_runtime::distributed::{serve, DistributedError, Traffic, Transport, WorkerScene};

/// This process's rank of the `mpirun` job.
#[cfg(feature = "mpi")]
pub(crate) fn transport() -> anyhow::Result<Box<dyn Transport>> {
    Ok(Box::new(rtsl_runtime::distributed::mpi::MpiTransport::init()?))
}

#[cfg(not(feature = "mpi"))]
pub(crate) fn transport() -> anyhow::Result<Box<dyn Transport>> {
    anyhow::bail!(
        "--mpi: this rtsl was built without MPI; build it with `cargo build --release --features mpi` \
         (which needs Open MPI: `apt-get install libopenmpi-dev openmpi-bin libclang-dev`) and run it under mpirun"
    )
}

/// Serves the master as a worker with the scene `scene` made (or the error that kept it from
/// loading, which the master reports once).
pub(crate) fn work<S: WorkerScene>(
    transport: &dyn Transport,
    scene: anyhow::Result<S>,
    pool: &rayon::ThreadPool,
) -> anyhow::Result<std::process::ExitCode> {
    let result: Result<(), DistributedError> = match scene {
        Ok(mut s) => serve(transport, Ok(&mut s), pool),
        Err(e) => serve(transport, Err(format!("{e:#}")), pool),
    };
    result?;
    Ok(std::process::ExitCode::SUCCESS)
}

/// "MPI traffic per frame: ..." of a frame's (or the mean frame's) traffic.
pub(crate) fn traffic_line(t: &Traffic) -> String {
    let kb = |b: u64| b as f64 / 1e3;
    format!(
        "MPI traffic per frame: {:.1} kB: pixels {:.1} kB, updates {:.2} kB, tile assignments {:.1} kB, counters {:.2} kB",
        kb(t.total()),
        kb(t.pixels),
        kb(t.updates),
        kb(t.control),
        kb(t.counters)
    )
}
