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
        let universe = mpi::initialize()
            .ok_or_else(|| ClusterError::Mpi("MPI was already initialised".into()))?;
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
        let mut status = std::mem::MaybeUninit::<ffi::MPI_Status>::uninit();
        // SAFETY: MPI writes the status when flag is set; it is read only then.
        let code = unsafe {
            ffi::MPI_Iprobe(
                from as c_int,
                TAG,
                ffi::RSMPI_COMM_WORLD,
                &mut flag,
                status.as_mut_ptr(),
            )
        };
        check(code, "MPI_Iprobe")?;
        if flag == 0 {
            return Ok(false);
        }
        // SAFETY: set by the successful probe above.
        let status = unsafe { status.assume_init() };
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
        // SAFETY: `into` holds `capped` bytes; MPI writes at most that many (a longer
        // message is truncated with an error code, checked below).
        let code = unsafe {
            ffi::MPI_Recv(
                into.as_mut_ptr() as *mut c_void,
                capped as c_int,
                ffi::RSMPI_UINT8_T,
                from as c_int,
                TAG,
                ffi::RSMPI_COMM_WORLD,
                ffi::RSMPI_STATUS_IGNORE,
            )
        };
        if len > capped {
            return Err(ClusterError::Malformed(format!(
                "a message of {len} bytes from rank {from}, over the {MAX_MESSAGE_BYTES}-byte budget"
            )));
        }
        check(code, "MPI_Recv")?;
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
        if !self.finalize
            && let Some(universe) = self.universe.take()
        {
            // MPI_Finalize synchronises with every rank, a lost one included: skip it.
            std::mem::forget(universe);
        }
    }
}
