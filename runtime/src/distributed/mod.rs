//! Rendering over several processes, as the paper's engine does (Wald, Benthin and Slusallek
//! 2002, section 2.3): rank 0 is the **master**, which runs the application, owns the scene and
//! the output; every other rank is a **worker**, which renders the tiles the master hands it and
//! sends their pixels back. The ranks talk through a [`Transport`]: MPI in real runs (`mpi.rs`,
//! behind the `mpi` feature, started with `mpirun`), channels between threads in tests
//! ([`LocalTransport`]).
//!
//! A frame: the master sends each worker the frame's update (what changed, for the worker to
//! apply to its own copy of the scene) and its first tiles; a worker brings its scene to the
//! frame's state, renders, and sends each finished tile back; each tile received earns its worker
//! the next one ([`schedule`]: the tiles it rendered last frame first, so that its caches stay
//! warm), until the master says no more will come; the worker then reports its counters. The
//! master assembles the image as a single process does ([`crate::render::TileRenderer::finish`]).
//! A viewer's pieces of work travel the same way, their units pixel lattices instead of tiles
//! ([`Job`], [`Master::trace_lattices`]). Another context is another scene (a RIB file's next
//! frame): before its first frame the workers drop their copy ([`Message::NewScene`]), and the
//! frame's update carries the new scene whole; they keep the meshes and texture levels they
//! fetched, which the new scene takes where their digests say they are the same.
//!
//! Invariants:
//! - The image is bit for bit the single-process image of the same world: a tile's pixels depend
//!   only on the world and the tile, a lattice's samples only on the world, the lattice and the
//!   pass (all sampling is hashed from the pixel and the shading point), and tiles and filter
//!   splats are put together in tile order whoever rendered them.
//! - A worker renders no tile of a frame before it has applied that frame's update, and every
//!   tile message names its frame: no image mixes two frames' states.
//! - A rank never waits without end on a peer that has stopped: the master's drop tells the
//!   workers to quit; under MPI a rank that dies or panics ends the whole job (`mpi.rs`), and in
//!   tests a receive gives up after a timeout.
//! - Ranks running another build or protocol version are refused at start-up
//!   ([`Master::connect`]).

pub mod fetch;
mod master;
pub mod message;
#[cfg(feature = "mpi")]
pub mod mpi;
pub mod schedule;
pub mod transport;
mod worker;

pub use master::{Demand, Master, TileQuarters, Traffic, WorkerTime};
pub use message::{FrameCounts, Job, LatticeUnit, Message, PROTOCOL_VERSION};
pub use transport::{LocalTransport, Transport, TransportError};
pub use worker::{serve, ReplicaScene, WorkerScene, DEFAULT_MESH_CACHE_BYTES};

use crate::render::FrameReport;
use std::time::Duration;

/// What went wrong in a distributed run, naming the rank where one is to blame.
#[derive(Debug, thiserror::Error)]
pub enum DistributedError {
    #[error(transparent)]
    Transport(#[from] TransportError),
    #[error("rank {rank} runs {what}")]
    Mismatch { rank: usize, what: String },
    #[error("rank {rank}: {message}")]
    Worker { rank: usize, message: String },
    #[error("rank {rank} broke the protocol: {message}")]
    Protocol { rank: usize, message: String },
    #[error(transparent)]
    Replica(#[from] crate::api::ReplicaError),
}

/// Adds a worker's counts to the master's report of a frame.
fn add_counts(report: &mut FrameReport, c: &FrameCounts) {
    let [primary, shadow, secondary, transparency] = c.rays;
    report.primary_rays += primary;
    report.shadow_rays += shadow;
    report.secondary_rays += secondary;
    report.transparency_rays += transparency;
    report.shaded_points += c.shaded_points;
    report.light_evaluations += c.light_evaluations;
    report.rays_cut += c.rays_cut;
    report.lights_dropped += c.lights_dropped;
    report.shading += Duration::from_nanos(c.shading_ns);
    report.light_paths += Duration::from_nanos(c.light_paths_ns);
    report.gathering += Duration::from_nanos(c.gathering_ns);
    for (total, &ns) in report.by_kind.iter_mut().zip(&c.kind_ns) {
        *total += Duration::from_nanos(ns);
    }
    for (name, kind, ns) in &c.by_shader {
        let Some(kind) = FrameCounts::kind(*kind) else { continue };
        match report.by_shader.iter_mut().find(|(n, k, _)| n == name && *k == kind) {
            Some((_, _, t)) => *t += Duration::from_nanos(*ns),
            None => report.by_shader.push((name.clone(), kind, Duration::from_nanos(*ns))),
        }
    }
    report.by_shader.sort_by(|a, b| b.2.cmp(&a.2).then_with(|| a.0.cmp(&b.0)));
    for m in &c.shader_messages {
        if !report.shader_messages.contains(m) {
            report.shader_messages.push(m.clone());
        }
    }
}
