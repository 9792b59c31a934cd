//! `--mpi`: the subcommands that render over the ranks of an `mpirun` job. Rank 0 is the master
//! (it loads the scene, prints and writes what a single process would); every other rank starts
//! with an empty scene, is sent the master's, and serves it as a worker
//! (`rtsl_runtime::distributed`).

use rtsl_runtime::distributed::{serve, ReplicaScene, Traffic, Transport};

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

/// Serves the master as a worker: a copy of the master's scene, sent to it frame by frame.
pub(crate) fn work(transport: &dyn Transport, pool: &rayon::ThreadPool) -> anyhow::Result<std::process::ExitCode> {
    serve(transport, Ok(&mut ReplicaScene::new()), pool)?;
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
