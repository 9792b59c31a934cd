//! Demand loading on a worker: the render threads' requests for the meshes of objects that rays
//! reached and the worker does not hold, passed to the thread that talks to the master, and the
//! master's answers passed back (the paper's section 5.4).
//!
//! A render thread that needs an object's mesh ([`MeshSource::fetch`], from the object's first
//! traversal) queues a request and waits; the worker's communication thread sends the queued
//! requests as one `Fetch` message at its next poll and hands each mesh of the `Meshes` answer to
//! the threads waiting for it. Other threads that reach the same object meanwhile wait on the
//! object itself (`Object::data`), so each object is fetched once.
//!
//! A fetch that fails (the answer is damaged, or never comes) leaves the object empty and is
//! recorded: the frame then ends with that failure, reported by the master, never a wrong image
//! passed off as right.

use crate::accel::object::MeshSource;
use crate::api::decode_mesh;
use crate::geometry::Mesh;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// How long a render thread waits for a mesh before it gives up on the master.
const FETCH_TIMEOUT: Duration = Duration::from_secs(300);

/// The link between a worker's render threads and its communication thread.
#[derive(Debug, Default)]
pub struct MeshLink {
    /// Requests not yet sent: an object and where its mesh's bytes go.
    queued: Mutex<Vec<(u32, Sender<Vec<u8>>)>>,
    /// The first fetch of this frame that failed.
    failure: Mutex<Option<String>>,
    fetched_objects: AtomicU64,
    fetched_bytes: AtomicU64,
}

impl MeshLink {
    pub fn new() -> Arc<MeshLink> {
        Arc::new(MeshLink::default())
    }

    /// The requests queued since the last call (communication thread).
    pub(super) fn take_requests(&self) -> Vec<(u32, Sender<Vec<u8>>)> {
        std::mem::take(&mut *self.queued.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// This frame's failure, objects fetched and their bytes; resets them for the next frame.
    pub(super) fn take_frame(&self) -> (Option<String>, u64, u64) {
        let failure = self.failure.lock().unwrap_or_else(PoisonError::into_inner).take();
        (failure, self.fetched_objects.swap(0, Ordering::Relaxed), self.fetched_bytes.swap(0, Ordering::Relaxed))
    }

    fn fail(&self, message: String) {
        self.failure.lock().unwrap_or_else(PoisonError::into_inner).get_or_insert(message);
    }
}

impl MeshSource for MeshLink {
    fn fetch(&self, key: u32) -> Arc<Mesh> {
        let (tx, rx): (Sender<Vec<u8>>, Receiver<Vec<u8>>) = channel();
        self.queued.lock().unwrap_or_else(PoisonError::into_inner).push((key, tx));
        let bytes = match rx.recv_timeout(FETCH_TIMEOUT) {
            Ok(bytes) => bytes,
            Err(_) => {
                self.fail(format!("the mesh of object {key} never came from the master"));
                return Arc::default();
            }
        };
        self.fetched_objects.fetch_add(1, Ordering::Relaxed);
        self.fetched_bytes.fetch_add(bytes.len() as u64, Ordering::Relaxed);
        if bytes.is_empty() {
            self.fail(format!("the master has no mesh for object {key}"));
            return Arc::default();
        }
        match decode_mesh(&bytes) {
            Ok(mesh) => Arc::new(mesh),
            Err(e) => {
                self.fail(format!("the mesh of object {key}: {e}"));
                Arc::default()
            }
        }
    }
}

/// The communication thread's side: requests sent and not yet answered.
#[derive(Default)]
pub(super) struct Pending(HashMap<u32, Vec<Sender<Vec<u8>>>>);

impl Pending {
    /// Takes `link`'s queued requests; returns the objects to ask the master for (those not
    /// already asked for).
    pub(super) fn take(&mut self, link: &MeshLink) -> Vec<u32> {
        let mut ask = Vec::new();
        for (object, tx) in link.take_requests() {
            let waiting = self.0.entry(object).or_default();
            if waiting.is_empty() {
                ask.push(object);
            }
            waiting.push(tx);
        }
        ask
    }

    /// Hands the master's answer to the threads waiting for it.
    pub(super) fn answer(&mut self, meshes: Vec<(u32, Vec<u8>)>) {
        for (object, bytes) in meshes {
            for tx in self.0.remove(&object).unwrap_or_default() {
                // A thread that gave up waiting has dropped its receiver.
                let _ = tx.send(bytes.clone());
            }
        }
    }
}
