//! A worker: a rank that renders the tiles the master hands it, on the threads of its own pool,
//! from its own copy of the scene, brought to each frame's state before any of that frame's tiles.

use super::message::{build_fingerprint, Message, PROTOCOL_VERSION};
use super::transport::Transport;
use super::DistributedError;
use crate::render::{TileRenderer, World};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::time::Instant;

/// A worker's copy of the scene.
pub trait WorkerScene {
    /// The world of the next frame, after applying the master's `update` for it (what an update
    /// holds is the application's business: a BART player sends the animation's time).
    fn world(&mut self, update: &[u8]) -> Result<World, String>;
    /// Takes back a frame's world once its tiles are rendered (to keep its BVHs for the next).
    fn finished(&mut self, world: World);
}

/// A scene that stays as it was loaded: every frame's update is empty.
impl WorkerScene for crate::api::Context {
    fn world(&mut self, update: &[u8]) -> Result<World, String> {
        if !update.is_empty() {
            return Err(format!("a scene that does not change was sent an update of {} bytes", update.len()));
        }
        self.build_world().map_err(|e| e.to_string())
    }

    fn finished(&mut self, world: World) {
        self.return_scene(world);
    }
}

/// Serves the master on rank 0 of `transport` until it says to stop: greets it (with `scene`'s
/// failure if the scene could not be loaded), then renders each frame's tiles on `pool`.
pub fn serve<T: Transport>(
    transport: &T,
    scene: Result<&mut dyn WorkerScene, String>,
    pool: &rayon::ThreadPool,
) -> Result<(), DistributedError> {
    let (mut scene, failure) = match scene {
        Ok(s) => (Some(s), None),
        Err(e) => (None, Some(e)),
    };
    let hello = Message::Hello {
        protocol: PROTOCOL_VERSION,
        build: build_fingerprint(),
        threads: pool.current_num_threads() as u32,
        failure: failure.clone(),
    };
    transport.send(0, &hello.encode())?;
    loop {
        match receive(transport)? {
            Message::Quit => return Ok(()),
            Message::Frame { frame, update, tiles, last } => {
                let world = match scene.as_deref_mut() {
                    Some(s) => s.world(&update),
                    None => Err(failure.clone().unwrap_or_default()),
                };
                match world {
                    Ok(world) => {
                        let quit = render_share(transport, &world, frame, tiles, last, pool)?;
                        if let Some(s) = scene.as_deref_mut() {
                            s.finished(world);
                        }
                        if quit {
                            return Ok(());
                        }
                    }
                    Err(message) => {
                        let done = Message::FrameDone { frame, counts: Default::default(), failure: Some(message) };
                        transport.send(0, &done.encode())?;
                    }
                }
            }
            _ => return Err(out_of_place(transport)),
        }
    }
}

/// The next message from the master.
fn receive<T: Transport>(transport: &T) -> Result<Message, DistributedError> {
    let (rank, bytes) = transport.recv()?;
    decode_from(transport, rank, &bytes)
}

fn decode_from<T: Transport>(transport: &T, rank: usize, bytes: &[u8]) -> Result<Message, DistributedError> {
    let me = transport.rank();
    if rank != 0 {
        return Err(DistributedError::Protocol { rank: me, message: format!("a message from rank {rank}") });
    }
    Message::decode(bytes).map_err(|message| DistributedError::Protocol { rank: me, message })
}

fn out_of_place<T: Transport>(transport: &T) -> DistributedError {
    DistributedError::Protocol { rank: transport.rank(), message: "a message out of place from the master".into() }
}

/// Renders this worker's share of a frame: the tiles it was given first, then those it gets for
/// each one it sends back, until the master says no more will come; then reports its counts.
/// Returns whether the master said to stop meanwhile.
fn render_share<T: Transport>(
    transport: &T,
    world: &World,
    frame: u64,
    first: Vec<u32>,
    mut last: bool,
    pool: &rayon::ThreadPool,
) -> Result<bool, DistributedError> {
    let start = Instant::now();
    let renderer = TileRenderer::new(world);
    let tiles = renderer.tiles();
    let mut queue: VecDeque<u32> = first.into();
    let take = |m: Message, queue: &mut VecDeque<u32>, last: &mut bool| match m {
        Message::Assign { frame: f, tiles, last: l } if f == frame => {
            queue.extend(tiles);
            *last |= l;
            Ok(false)
        }
        Message::Quit => Ok(true),
        _ => Err(out_of_place(transport)),
    };
    loop {
        while let Some((rank, bytes)) = transport.try_recv()? {
            if take(decode_from(transport, rank, &bytes)?, &mut queue, &mut last)? {
                return Ok(true);
            }
        }
        if queue.is_empty() {
            if last {
                break;
            }
            if take(receive(transport)?, &mut queue, &mut last)? {
                return Ok(true);
            }
            continue;
        }
        let batch: Vec<u32> = (0..pool.current_num_threads()).map_while(|_| queue.pop_front()).collect();
        if let Some(&bad) = batch.iter().find(|&&t| t as usize >= tiles.len()) {
            return Err(DistributedError::Protocol {
                rank: transport.rank(),
                message: format!("the master handed out tile {bad} of a frame of {} tiles", tiles.len()),
            });
        }
        let done: Vec<(u32, Vec<u8>)> = pool.install(|| {
            batch
                .par_iter()
                .map(|&t| {
                    let mut pixels = Vec::new();
                    renderer.render_tile(&tiles[t as usize]).encode(&mut pixels);
                    (t, pixels)
                })
                .collect()
        });
        for (tile, pixels) in done {
            transport.send(0, &Message::Tile { frame, tile, pixels }.encode())?;
        }
    }
    let counts = super::master::counts_of(&renderer.report(start));
    transport.send(0, &Message::FrameDone { frame, counts, failure: None }.encode())?;
    Ok(false)
}
