//! A sum over ranks that runs while the rank computes (`MPI_Iallreduce`).
//!
//! Why: a blocking all-reduce in the middle of a step makes every rank wait there for the
//! slowest one. Started where its values are ready and finished where they are first
//! needed, the sum lets a rank that arrived early compute meanwhile and hides the
//! reduction's own latency; a rank that fell behind is still waited for at the next
//! blocking collective (docs/BENCHMARKS.md, session 67).

use std::marker::PhantomData;
use std::os::raw::c_void;

use super::{to_count, Domain};

/// The buffers of a sum, kept by a caller that sums every step and handed back to
/// [`Domain::start_sum`], so that a step allocates nothing once they have grown.
#[derive(Debug, Default)]
pub struct SumBuffers {
    send: Vec<f64>,
    recv: Vec<f64>,
}

/// A sum in flight, returned by [`Domain::start_sum`]; [`PendingSum::finish`] waits for it.
///
/// It owns both buffers, so nothing the caller does can free or change memory MPI still
/// reads or writes. Dropping it without `finish` waits for completion.
pub struct PendingSum<'d> {
    buffers: SumBuffers,
    request: mpi::ffi::MPI_Request,
    /// The request has completed.
    done: bool,
    // Ties the sum to the Domain (MPI must outlive it) and keeps it on its thread.
    _domain: PhantomData<&'d Domain>,
}

impl Domain {
    /// Starts the element-wise sum over ranks of `values` and returns without waiting; the
    /// values are copied, so the caller may change `values` meanwhile.
    ///
    /// All ranks must call, with slices of the same length; the sum is one collective, in
    /// the same order as the others on every rank.
    ///
    /// # Panics
    /// Above 2³¹−1 values.
    pub fn start_sum(&self, values: &[f64], buffers: SumBuffers) -> PendingSum<'_> {
        let mut pending = PendingSum {
            // SAFETY: a constant the MPI library defines
            request: unsafe { mpi::ffi::RSMPI_REQUEST_NULL },
            done: false,
            buffers,
            _domain: PhantomData,
        };
        let b = &mut pending.buffers;
        b.send.clear();
        b.send.extend_from_slice(values);
        b.recv.clear();
        b.recv.resize(values.len(), 0.0);
        let count = to_count(values.len());
        // SAFETY: both buffers are heap allocations owned by `pending`, not resized or moved
        // out until the request has completed (finish or Drop waits); moving `pending` does
        // not move their heap data. The datatype, the operation and the counts match.
        unsafe {
            mpi::ffi::MPI_Iallreduce(
                b.send.as_ptr() as *const c_void,
                b.recv.as_mut_ptr() as *mut c_void,
                count,
                mpi::ffi::RSMPI_DOUBLE,
                mpi::ffi::RSMPI_SUM,
                self.raw_comm(),
                &mut pending.request,
            );
        }
        pending
    }
}

impl PendingSum<'_> {
    /// Waits for the sum, writes it into `values` (the length given to `start_sum`) and
    /// returns the buffers for the next one.
    ///
    /// # Panics
    /// When `values` has another length than the sum.
    pub fn finish(mut self, values: &mut [f64]) -> SumBuffers {
        self.wait();
        values.copy_from_slice(&self.buffers.recv);
        std::mem::take(&mut self.buffers)
    }

    fn wait(&mut self) {
        if self.done {
            return;
        }
        // SAFETY: the request is live; MPI_Status is a plain C struct, zeroed is valid and
        // MPI overwrites it.
        unsafe {
            let mut status: mpi::ffi::MPI_Status = std::mem::zeroed();
            mpi::ffi::MPI_Wait(&mut self.request, &mut status);
        }
        self.done = true;
    }
}

impl Drop for PendingSum<'_> {
    fn drop(&mut self) {
        // MPI may still read the send buffer and write the receive buffer: wait first.
        self.wait();
    }
}

#[cfg(test)]
mod tests {
    use crate::domain::with_test_domain;

    #[test]
    fn a_sum_started_then_finished_is_the_blocking_sum_and_keeps_its_buffers() {
        with_test_domain(|d| {
            let values = [1.5, -2.0, 0.0, 7.25];
            let mut blocking = values;
            d.sum_in_place(&mut blocking);
            let mut buffers = Default::default();
            for _ in 0..2 {
                let mut caller = values;
                let pending = d.start_sum(&caller, buffers);
                // the caller's slice is free while the sum is in flight
                caller = [9.0; 4];
                assert_eq!(caller, [9.0; 4]);
                buffers = pending.finish(&mut caller);
                assert_eq!(caller, blocking);
            }
            // dropped unfinished: waits, does not leak a request into the next collective
            drop(d.start_sum(&values, buffers));
            let mut again = values;
            d.sum_in_place(&mut again);
            assert_eq!(again, blocking);
        });
    }
}
