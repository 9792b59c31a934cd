//! How ranks reach each other: a [`Transport`] moves whole messages (byte strings) between the
//! processes of a fixed group, numbered 0 (the master) to `size - 1`. MPI is the transport of
//! real runs (`super::mpi`, behind the `mpi` feature); [`LocalTransport`] joins threads of one
//! process through channels, so that the master and its workers are tested without MPI.
//!
//! Invariant: messages from one rank to another arrive in the order they were sent (MPI's
//! non-overtaking rule; a channel's order); the protocol relies on it.

use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::time::Duration;

/// A transport failed: the message says what and, where it can, which rank.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct TransportError(pub String);

/// Whole messages between the ranks of a fixed group.
pub trait Transport {
    /// This process's rank: 0 is the master.
    fn rank(&self) -> usize;
    /// How many ranks the group has.
    fn size(&self) -> usize;
    /// Sends `bytes` to rank `to`, without waiting for `to` to receive them: the master and a
    /// worker may each send the other a large message at once (meshes one way, pixels the other),
    /// and two sends that each waited for the other's receive would wait for ever. Messages
    /// between two ranks arrive in the order they were sent. The transport keeps `bytes` until
    /// they are sent: a message is never copied on its way out.
    fn send(&self, to: usize, bytes: Vec<u8>) -> Result<(), TransportError>;
    /// The next message from any rank, and its sender, waiting for one.
    fn recv(&self) -> Result<(usize, Vec<u8>), TransportError>;
    /// The next message from any rank if one has arrived, without waiting.
    fn try_recv(&self) -> Result<Option<(usize, Vec<u8>)>, TransportError>;
    /// Whether messages are still under way, either way, that move only while this rank calls
    /// the transport (MPI's large messages go by rendezvous: the receiver waits until the
    /// sender's side progresses, and the other way round). A rank with such messages calls again
    /// soon instead of napping.
    fn sending(&self) -> bool {
        false
    }
    /// Gives back the bytes of a message [`Transport::recv`] returned, once read, for a later
    /// message to arrive in (a transport that keeps none drops them).
    fn recycle(&self, bytes: Vec<u8>) {
        drop(bytes);
    }
    /// Whether [`Transport::recv`] polls without napping between polls: for a rank with a core
    /// of its own, where a nap only adds to each answer's latency (a transport that never naps
    /// ignores it).
    fn set_spinning(&self, spinning: bool) {
        let _ = spinning;
    }
    /// Whether every rank of the group shares this rank's memory (threads of one process, or
    /// processes of one machine, between which a message is a copy in memory): what travels
    /// then goes plain, not deflated ([`super::Master::set_deflate`]).
    fn shares_memory(&self) -> bool {
        true
    }
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn rank(&self) -> usize {
        (**self).rank()
    }
    fn size(&self) -> usize {
        (**self).size()
    }
    fn send(&self, to: usize, bytes: Vec<u8>) -> Result<(), TransportError> {
        (**self).send(to, bytes)
    }
    fn recv(&self) -> Result<(usize, Vec<u8>), TransportError> {
        (**self).recv()
    }
    fn try_recv(&self) -> Result<Option<(usize, Vec<u8>)>, TransportError> {
        (**self).try_recv()
    }
    fn sending(&self) -> bool {
        (**self).sending()
    }
    fn recycle(&self, bytes: Vec<u8>) {
        (**self).recycle(bytes)
    }
    fn set_spinning(&self, spinning: bool) {
        (**self).set_spinning(spinning)
    }
    fn shares_memory(&self) -> bool {
        (**self).shares_memory()
    }
}

/// One rank of a group of threads in this process (see [`LocalTransport::group`]).
pub struct LocalTransport {
    rank: usize,
    peers: Vec<Sender<(usize, Vec<u8>)>>,
    inbox: Receiver<(usize, Vec<u8>)>,
    /// How long [`Transport::recv`] waits before it reports a hang as an error.
    timeout: Duration,
}

impl LocalTransport {
    /// `size` connected ranks, one for each thread that plays one; a receive that waits longer than
    /// `timeout` fails, so a protocol error shows as an error rather than a hang.
    pub fn group(size: usize, timeout: Duration) -> Vec<LocalTransport> {
        let (senders, inboxes): (Vec<_>, Vec<_>) = (0..size).map(|_| channel()).unzip();
        inboxes
            .into_iter()
            .enumerate()
            .map(|(rank, inbox)| LocalTransport { rank, peers: senders.clone(), inbox, timeout })
            .collect()
    }
}

impl Transport for LocalTransport {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.peers.len()
    }

    fn send(&self, to: usize, bytes: Vec<u8>) -> Result<(), TransportError> {
        let peer = self.peers.get(to).ok_or_else(|| TransportError(format!("there is no rank {to}")))?;
        peer.send((self.rank, bytes)).map_err(|_| TransportError(format!("rank {to} has stopped")))
    }

    fn recv(&self) -> Result<(usize, Vec<u8>), TransportError> {
        self.inbox.recv_timeout(self.timeout).map_err(|e| match e {
            RecvTimeoutError::Timeout => {
                TransportError(format!("rank {}: no message for {:?}", self.rank, self.timeout))
            }
            RecvTimeoutError::Disconnected => {
                TransportError(format!("rank {}: every other rank has stopped", self.rank))
            }
        })
    }

    fn try_recv(&self) -> Result<Option<(usize, Vec<u8>)>, TransportError> {
        match self.inbox.try_recv() {
            Ok(m) => Ok(Some(m)),
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => {
                Err(TransportError(format!("rank {}: every other rank has stopped", self.rank)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_arrive_in_order_with_their_sender() {
        let group = LocalTransport::group(3, Duration::from_secs(5));
        for k in 0..3u8 {
            group[1].send(0, vec![1, k]).unwrap();
            group[2].send(0, vec![2, k]).unwrap();
        }
        let mut from = [Vec::new(), Vec::new(), Vec::new()];
        for _ in 0..6 {
            let (rank, bytes) = group[0].recv().unwrap();
            assert_eq!(bytes[0] as usize, rank);
            from[rank].push(bytes[1]);
        }
        assert_eq!(from[1], [0, 1, 2]);
        assert_eq!(from[2], [0, 1, 2]);
        assert_eq!(group[0].try_recv(), Ok(None));
    }

    #[test]
    fn a_silent_group_is_an_error_not_a_hang() {
        let group = LocalTransport::group(2, Duration::from_millis(20));
        assert!(group[0].recv().is_err());
        assert!(group[0].send(5, vec![]).is_err());
    }
}
