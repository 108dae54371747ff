//! How cluster processes reach each other: the [`Transport`] trait, and an in-process
//! implementation over channels for tests.

use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};

use super::ClusterError;

/// Ordered, reliable, non-blocking delivery of byte messages between the processes of one
/// cluster, numbered 0 (the master) to `size() - 1`. Nothing here ever blocks: waits with
/// timeouts are built on [`Transport::try_receive`].
pub trait Transport {
    /// This process's number.
    fn rank(&self) -> usize;
    /// How many processes the cluster has.
    fn size(&self) -> usize;
    /// Starts sending `bytes` to `to` and returns at once (the bytes are copied).
    fn send(&mut self, to: usize, bytes: &[u8]) -> Result<(), ClusterError>;
    /// The next message from `from` into `into`, if one has arrived.
    fn try_receive(&mut self, from: usize, into: &mut Vec<u8>) -> Result<bool, ClusterError>;
    /// Gives up on `peer` (lost): nothing more is sent to it or read from it, and sends to
    /// it still in flight are abandoned.
    fn abandon(&mut self, peer: usize);
    /// The name of the machine this process runs on.
    fn host(&self) -> String;
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn rank(&self) -> usize {
        (**self).rank()
    }
    fn size(&self) -> usize {
        (**self).size()
    }
    fn send(&mut self, to: usize, bytes: &[u8]) -> Result<(), ClusterError> {
        (**self).send(to, bytes)
    }
    fn try_receive(&mut self, from: usize, into: &mut Vec<u8>) -> Result<bool, ClusterError> {
        (**self).try_receive(from, into)
    }
    fn abandon(&mut self, peer: usize) {
        (**self).abandon(peer)
    }
    fn host(&self) -> String {
        (**self).host()
    }
}

/// A cluster of threads in one process (tests): ordered channels between every pair.
#[derive(Debug)]
pub struct MemoryTransport {
    rank: usize,
    to: Vec<Option<Sender<Vec<u8>>>>,
    from: Vec<Option<Receiver<Vec<u8>>>>,
}

impl MemoryTransport {
    /// `size` connected transports, ranks 0 to `size - 1`.
    pub fn cluster(size: usize) -> Vec<MemoryTransport> {
        let mut all: Vec<MemoryTransport> = (0..size)
            .map(|rank| MemoryTransport {
                rank,
                to: (0..size).map(|_| None).collect(),
                from: (0..size).map(|_| None).collect(),
            })
            .collect();
        for a in 0..size {
            for b in 0..size {
                if a != b {
                    let (tx, rx) = channel();
                    all[a].to[b] = Some(tx);
                    all[b].from[a] = Some(rx);
                }
            }
        }
        all
    }
}

impl Transport for MemoryTransport {
    fn rank(&self) -> usize {
        self.rank
    }
    fn size(&self) -> usize {
        self.to.len()
    }
    fn send(&mut self, to: usize, bytes: &[u8]) -> Result<(), ClusterError> {
        // A peer that has gone (its transport dropped) loses the message, as MPI would.
        if let Some(Some(tx)) = self.to.get(to) {
            let _ = tx.send(bytes.to_vec());
        }
        Ok(())
    }
    fn try_receive(&mut self, from: usize, into: &mut Vec<u8>) -> Result<bool, ClusterError> {
        let Some(Some(rx)) = self.from.get(from) else {
            return Ok(false);
        };
        match rx.try_recv() {
            Ok(bytes) => {
                into.clear();
                into.extend_from_slice(&bytes);
                Ok(true)
            }
            Err(TryRecvError::Empty | TryRecvError::Disconnected) => Ok(false),
        }
    }
    fn abandon(&mut self, peer: usize) {
        if let Some(slot) = self.to.get_mut(peer) {
            *slot = None;
        }
        if let Some(slot) = self.from.get_mut(peer) {
            *slot = None;
        }
    }
    fn host(&self) -> String {
        format!("thread-{}", self.rank)
    }
}
