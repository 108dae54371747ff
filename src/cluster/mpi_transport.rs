//! The cluster's [`Transport`] over MPI (`mpirun` starts one process per rank; Open MPI or
//! MPICH).
//!
//! Sends are `MPI_Isend` from a buffer this module owns until the send completes, and
//! receives poll with `MPI_Iprobe`, so a dead or stalled peer never blocks a call: the
//! session's timeouts decide. Errors return codes (`MPI_ERRORS_RETURN`) instead of aborting
//! the job, so that a peer's death is reported rather than fatal. rsmpi's safe API cannot do
//! either (its requests must complete in a scope or panic; it keeps the fatal handler), hence
//! the few FFI calls below, each with its safety argument.
#![allow(unsafe_code)]

use std::os::raw::{c_int, c_void};

use mpi::ffi;
use mpi::traits::Communicator;

use super::messages::MAX_MESSAGE_BYTES;
use super::{ClusterError, Transport};

/// The one tag every omnicave message uses (MPI keeps messages between two ranks with one
/// tag in order).
const TAG: c_int = 7901;

/// How long a message whose first bytes have arrived may take to arrive whole.
const RECEIVE_LIMIT: std::time::Duration = std::time::Duration::from_secs(10);
/// How long dropping the transport waits for its sends to complete before finalizing.
const DRAIN_LIMIT: std::time::Duration = std::time::Duration::from_secs(2);
/// Between two tests of a pending request: the render thread sleeps rather than spins (a
/// settings message of a few MiB arrives in a few of these).
const TEST_INTERVAL: std::time::Duration = std::time::Duration::from_micros(200);

/// How waiting for a request ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Waited {
    Done,
    /// MPI_Test returned this error code: the request may still be pending.
    Failed(c_int),
    /// Not complete by the deadline: the request is still pending.
    TimedOut,
}

/// What a receive's wait leaves: the message, an error with the buffer ours again, or an error
/// with the request still pending (the buffer and the peer must be given up).
#[derive(Debug)]
enum Received {
    Whole,
    Failed(ClusterError),
    GiveUp(ClusterError),
}

/// Judges a receive of `len` bytes (`capped` of them read) from rank `from` after
/// [`wait_for_request`]; `pending`: the request handle is not null (MPI may still write).
fn after_receive(
    waited: Waited,
    pending: bool,
    len: usize,
    capped: usize,
    from: usize,
) -> Received {
    match waited {
        Waited::Done => Received::Whole,
        // Completed with an error (MPI set the handle to null): the buffer is ours again.
        Waited::Failed(_) if !pending && len > capped => {
            Received::Failed(ClusterError::Malformed(format!(
                "a message of {len} bytes from rank {from}, over the {MAX_MESSAGE_BYTES}-byte budget"
            )))
        }
        Waited::Failed(code) if !pending => Received::Failed(ClusterError::Mpi(format!(
            "receiving {len} bytes from rank {from}: MPI_Test failed with MPI error code {code}"
        ))),
        Waited::Failed(code) => Received::GiveUp(ClusterError::Mpi(format!(
            "receiving {len} bytes from rank {from}: MPI_Test failed with MPI error code \
             {code} and the receive is still pending; rank {from} is given up"
        ))),
        Waited::TimedOut => Received::GiveUp(ClusterError::Mpi(format!(
            "a message of {len} bytes from rank {from} did not arrive within {} s",
            RECEIVE_LIMIT.as_secs()
        ))),
    }
}

/// Tests a request (`test` gives MPI_Test's code and flag) until it completes, fails or
/// `limit` passes, sleeping [`TEST_INTERVAL`] between tests. After `Failed` or `TimedOut`
/// MPI may still write the request's buffer: the caller must give it up.
fn wait_for_request(limit: std::time::Duration, mut test: impl FnMut() -> (c_int, bool)) -> Waited {
    let start = std::time::Instant::now();
    loop {
        match test() {
            (0, true) => return Waited::Done,
            (0, false) => {}
            (code, _) => return Waited::Failed(code),
        }
        if start.elapsed() > limit {
            return Waited::TimedOut;
        }
        std::thread::sleep(TEST_INTERVAL);
    }
}

/// A send in flight: MPI reads `bytes` until `request` completes.
struct InFlight {
    request: ffi::MPI_Request,
    bytes: Vec<u8>,
}

/// MPI's world communicator as a [`Transport`]. Dropping it finalizes MPI, unless
/// [`MpiTransport::skip_finalize`] was called (after a lost peer, whose absence would make
/// `MPI_Finalize` wait for ever).
pub struct MpiTransport {
    universe: Option<mpi::environment::Universe>,
    rank: usize,
    size: usize,
    in_flight: Vec<Vec<InFlight>>,
    /// Completed send buffers, reused (no allocation per frame once warm).
    spare: Vec<Vec<u8>>,
    abandoned: Vec<bool>,
    finalize: bool,
}

impl std::fmt::Debug for MpiTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "MpiTransport(rank {} of {})", self.rank, self.size)
    }
}

fn check(code: c_int, what: &str) -> Result<(), ClusterError> {
    // MPI_SUCCESS is 0 in every implementation.
    if code == 0 {
        Ok(())
    } else {
        Err(ClusterError::Mpi(format!(
            "{what} failed with MPI error code {code}"
        )))
    }
}

impl MpiTransport {
    /// Initialises MPI (once per process) and makes communication errors return codes.
    pub fn init() -> Result<Self, ClusterError> {
        // Only the main thread calls MPI, but the process has other threads (tracking,
        // gamepads): "funneled" is the level that says so.
        use mpi::environment::Threading;
        let (universe, provided) = mpi::initialize_with_threading(Threading::Funneled)
            .ok_or_else(|| ClusterError::Mpi("MPI was already initialised".into()))?;
        if provided == Threading::Single {
            return Err(ClusterError::Mpi(
                "this MPI library provides only MPI_THREAD_SINGLE; omnicave has other threads \
                 (tracking, gamepads) and needs MPI_THREAD_FUNNELED or more"
                    .into(),
            ));
        }
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        // SAFETY: MPI is initialised; both handles are MPI's predefined constants.
        let code = unsafe {
            ffi::MPI_Comm_set_errhandler(ffi::RSMPI_COMM_WORLD, ffi::RSMPI_ERRORS_RETURN)
        };
        check(code, "MPI_Comm_set_errhandler")?;
        Ok(Self {
            universe: Some(universe),
            rank,
            size,
            in_flight: (0..size).map(|_| Vec::new()).collect(),
            spare: Vec::new(),
            abandoned: vec![false; size],
            finalize: true,
        })
    }

    /// Leaves MPI without `MPI_Finalize` (a peer was lost: finalizing would wait for it).
    pub fn skip_finalize(&mut self) {
        self.finalize = false;
    }

    /// Returns the buffers of completed sends to `peer` to the spare pool.
    fn reap(&mut self, peer: usize) -> Result<(), ClusterError> {
        let list = &mut self.in_flight[peer];
        let mut i = 0;
        while i < list.len() {
            let mut flag: c_int = 0;
            // SAFETY: `request` came from MPI_Isend and has not completed (completed ones
            // are removed below); the status is ignored.
            let code =
                unsafe { ffi::MPI_Test(&mut list[i].request, &mut flag, ffi::RSMPI_STATUS_IGNORE) };
            check(code, "MPI_Test")?;
            if flag != 0 {
                let done = list.swap_remove(i);
                self.spare.push(done.bytes);
            } else {
                i += 1;
            }
        }
        Ok(())
    }
}

impl Transport for MpiTransport {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn send(&mut self, to: usize, bytes: &[u8]) -> Result<(), ClusterError> {
        if to >= self.size || to == self.rank || self.abandoned[to] {
            return Ok(());
        }
        self.reap(to)?;
        let mut buf = self.spare.pop().unwrap_or_default();
        buf.clear();
        buf.extend_from_slice(bytes);
        let count = c_int::try_from(buf.len())
            .map_err(|_| ClusterError::Mpi(format!("message of {} bytes", buf.len())))?;
        let mut request = std::mem::MaybeUninit::<ffi::MPI_Request>::uninit();
        // SAFETY: `buf` is moved into `in_flight` right after and neither read mutably nor
        // dropped until MPI_Test reports the send complete (or the peer is abandoned, when it
        // is leaked); moving a Vec does not move its heap buffer. Count and datatype describe
        // exactly its bytes.
        let code = unsafe {
            ffi::MPI_Isend(
                buf.as_ptr() as *const c_void,
                count,
                ffi::RSMPI_UINT8_T,
                to as c_int,
                TAG,
                ffi::RSMPI_COMM_WORLD,
                request.as_mut_ptr(),
            )
        };
        check(code, "MPI_Isend")?;
        // SAFETY: a successful MPI_Isend wrote the request handle.
        let request = unsafe { request.assume_init() };
        self.in_flight[to].push(InFlight {
            request,
            bytes: buf,
        });
        Ok(())
    }

    fn try_receive(&mut self, from: usize, into: &mut Vec<u8>) -> Result<bool, ClusterError> {
        if from >= self.size || from == self.rank || self.abandoned[from] {
            return Ok(false);
        }
        let mut flag: c_int = 0;
        let mut message = std::mem::MaybeUninit::<ffi::MPI_Message>::uninit();
        let mut status = std::mem::MaybeUninit::<ffi::MPI_Status>::uninit();
        // SAFETY: MPI writes the message handle and the status when flag is set; they are
        // read only then. The matched message is taken out of the queue (no other receive
        // can take it), so the receive below gets exactly it.
        let code = unsafe {
            ffi::MPI_Improbe(
                from as c_int,
                TAG,
                ffi::RSMPI_COMM_WORLD,
                &mut flag,
                message.as_mut_ptr(),
                status.as_mut_ptr(),
            )
        };
        check(code, "MPI_Improbe")?;
        if flag == 0 {
            return Ok(false);
        }
        // SAFETY: both set by the successful probe above.
        let (mut message, status) = unsafe { (message.assume_init(), status.assume_init()) };
        let mut count: c_int = 0;
        // SAFETY: a valid status from the probe.
        let code = unsafe { ffi::MPI_Get_count(&status, ffi::RSMPI_UINT8_T, &mut count) };
        check(code, "MPI_Get_count")?;
        let len = usize::try_from(count).unwrap_or(0);
        // Over budget: received into a capped buffer (MPI truncates and reports it), so the
        // message is consumed and refused by its size.
        let capped = len.min(MAX_MESSAGE_BYTES + 1);
        into.clear();
        into.resize(capped, 0);
        let mut request = std::mem::MaybeUninit::<ffi::MPI_Request>::uninit();
        // SAFETY: `into` holds `capped` bytes and is not touched until the request completes
        // below (or is leaked if it never does); MPI writes at most that many.
        let code = unsafe {
            ffi::MPI_Imrecv(
                into.as_mut_ptr() as *mut c_void,
                capped as c_int,
                ffi::RSMPI_UINT8_T,
                &mut message,
                request.as_mut_ptr(),
            )
        };
        check(code, "MPI_Imrecv")?;
        // SAFETY: a successful MPI_Imrecv wrote the request handle.
        let mut request = unsafe { request.assume_init() };
        // A large message (the settings) may still be arriving: wait for it, bounded, so a
        // sender that dies half-way cannot block this process.
        let waited = wait_for_request(RECEIVE_LIMIT, || {
            let mut done: c_int = 0;
            // SAFETY: the pending request from MPI_Imrecv above, tested until it completes.
            let code = unsafe { ffi::MPI_Test(&mut request, &mut done, ffi::RSMPI_STATUS_IGNORE) };
            (code, done != 0)
        });
        // SAFETY: comparing two request handles reads neither's buffer.
        let pending = request != unsafe { ffi::RSMPI_REQUEST_NULL };
        match after_receive(waited, pending, len, capped, from) {
            Received::Whole => {}
            Received::Failed(e) => return Err(e),
            // MPI may still write into the buffer: give it up for good, and the peer with it
            // (its next message could not be told from this one's rest).
            Received::GiveUp(e) => {
                std::mem::forget(std::mem::take(into));
                self.abandon(from);
                return Err(e);
            }
        }
        if len > capped {
            return Err(ClusterError::Malformed(format!(
                "a message of {len} bytes from rank {from}, over the {MAX_MESSAGE_BYTES}-byte budget"
            )));
        }
        Ok(true)
    }

    fn abandon(&mut self, peer: usize) {
        if peer >= self.size {
            return;
        }
        self.abandoned[peer] = true;
        // Sends to a lost peer may never complete: MPI may still read their buffers, so they
        // are leaked (a few hundred bytes per lost node) rather than freed.
        for flight in self.in_flight[peer].drain(..) {
            std::mem::forget(flight.bytes);
        }
        self.finalize = false;
    }

    fn host(&self) -> String {
        mpi::environment::processor_name().unwrap_or_default()
    }
}

impl Drop for MpiTransport {
    fn drop(&mut self) {
        // MPI_Finalize with sends still pending is erroneous: let them complete, bounded.
        let start = std::time::Instant::now();
        while self.finalize && self.in_flight.iter().any(|l| !l.is_empty()) {
            for peer in 0..self.size {
                if self.reap(peer).is_err() {
                    self.finalize = false;
                }
            }
            if start.elapsed() > DRAIN_LIMIT {
                self.finalize = false;
            }
            std::thread::sleep(TEST_INTERVAL);
        }
        if !self.finalize {
            // Sends that never completed: MPI may still read their buffers.
            for list in &mut self.in_flight {
                for flight in list.drain(..) {
                    std::mem::forget(flight.bytes);
                }
            }
            if let Some(universe) = self.universe.take() {
                // MPI_Finalize synchronises with every rank, a lost one included: skip it.
                std::mem::forget(universe);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn waiting_for_a_request_ends_done_failed_or_timed_out() {
        let mut calls = 0;
        let done = wait_for_request(Duration::from_secs(1), || {
            calls += 1;
            (0, calls == 3)
        });
        assert_eq!((done, calls), (Waited::Done, 3));
        // An error code ends the wait at once, whatever the flag says.
        assert_eq!(
            wait_for_request(Duration::from_secs(1), || (15, false)),
            Waited::Failed(15)
        );
        // Never complete: out by the deadline, having slept between tests (not spun).
        let mut tests = 0;
        let start = std::time::Instant::now();
        let waited = wait_for_request(Duration::from_millis(20), || {
            tests += 1;
            (0, false)
        });
        assert_eq!(waited, Waited::TimedOut);
        assert!(start.elapsed() >= Duration::from_millis(20));
        // 20 ms at one test per 200 µs sleep is at most ~100 tests; a spin would make
        // hundreds of thousands.
        assert!(tests <= 150, "{tests} tests in 20 ms");
    }

    #[test]
    fn a_failed_receive_still_pending_gives_up_the_buffer_and_the_peer() {
        let (len, from) = (4096, 2);
        assert!(matches!(
            after_receive(Waited::Done, false, len, len, from),
            Received::Whole
        ));
        // MPI_Test failed and nulled the handle: an error, the buffer is ours to reuse.
        let failed = after_receive(Waited::Failed(15), false, len, len, from);
        assert!(
            matches!(&failed, Received::Failed(ClusterError::Mpi(m)) if m.contains("code 15")),
            "{failed:?}"
        );
        // Over the budget and failed (truncated): named as the budget.
        let over = after_receive(Waited::Failed(15), false, len, 1024, from);
        assert!(
            matches!(&over, Received::Failed(ClusterError::Malformed(m)) if m.contains("budget")),
            "{over:?}"
        );
        // Failed with the request still pending, or never completing: give up, naming the rank.
        for waited in [Waited::Failed(15), Waited::TimedOut] {
            let pending = after_receive(waited, true, len, len, from);
            assert!(
                matches!(&pending, Received::GiveUp(ClusterError::Mpi(m)) if m.contains("rank 2")),
                "{pending:?}"
            );
        }
        let timed_out = after_receive(Waited::TimedOut, false, len, len, from);
        assert!(matches!(timed_out, Received::GiveUp(_)), "{timed_out:?}");
    }
}
