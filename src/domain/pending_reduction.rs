//! A sum or maximum over ranks that runs while the rank computes.
//!
//! Why: a blocking all-reduce in the middle of a step makes every rank wait there for the
//! slowest one. Started where its values are ready and finished where they are first
//! needed, the reduction lets a rank that arrived early compute meanwhile.
//!
//! How it is carried out decides whether that works. Neither form is sure to complete
//! while another rank stays outside MPI: on Open MPI's shared-memory transport a message
//! above the eager limit (4 KiB) but below what it moves by single copy moves only when its
//! sender is inside MPI again (in session 68 a 96 kB one did not arrive in 30 s while its
//! sender slept; a 1 MiB one did). So a reduction's rounds advance in whatever MPI calls
//! the ranks make after starting it: the halo's, the output's, the next reduction's.
//! `MPI_Iallreduce` (Open MPI's libnbc) takes two dependent rounds on two ranks (a binomial
//! tree: the root receives, combines, then sends the result back); up to
//! [`EXCHANGE_RANKS_MAX`] ranks every rank instead sends its values to every other one at
//! the start and combines what it received at the finish, in rank order: one round.
//! Measured on the 2000-grain cell with the rebuild decision's maximum started at a step's
//! end and finished after the next force stage, the exchange took the ranks' wait in
//! `sync` from 6.6 to 4.5 ms per step on average, where `MPI_Iallreduce` left it at 8.6 /
//! 6.3 (docs/BENCHMARKS.md, session 68). Beyond that many ranks the exchange's p − 1
//! messages per rank and reduction grow with the job, and `MPI_Iallreduce` is used.

use std::marker::PhantomData;
use std::os::raw::c_void;

use super::{to_count, Domain};

/// Ranks up to which a reduction is one exchange of every rank's values with every other
/// rank (see the module docs); above, `MPI_Iallreduce`.
pub const EXCHANGE_RANKS_MAX: usize = 8;

/// How values from different ranks combine, element by element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Combine {
    /// Added in rank order (the same bits on every rank).
    Sum,
    /// The largest.
    Max,
}

/// The buffers of a reduction, kept by a caller that reduces every step and handed back
/// to [`Domain::start_reduction`], so that a step allocates nothing once they have grown.
/// It also holds the exchange's sends, which complete when their receivers take them:
/// the next start (or dropping the buffers) waits for them, not the finish.
#[derive(Debug, Default)]
pub struct ReductionBuffers<'d> {
    send: Vec<f64>,
    recv: Vec<f64>,
    sends: Vec<mpi::ffi::MPI_Request>,
    /// The exchange's receives, or the one `MPI_Iallreduce` request, of the reduction
    /// these buffers are lent to.
    receives: Vec<mpi::ffi::MPI_Request>,
    // Live requests need MPI: tie the buffers to the Domain.
    _domain: PhantomData<&'d Domain>,
}

impl ReductionBuffers<'_> {
    fn wait_for_sends(&mut self) {
        wait_all(&mut self.sends);
        self.sends.clear();
    }
}

impl Drop for ReductionBuffers<'_> {
    fn drop(&mut self) {
        // MPI may still write the receive buffer, and a receiver read the send buffer
        wait_all(&mut self.receives);
        self.wait_for_sends();
    }
}

/// A reduction in flight, returned by [`Domain::start_reduction`];
/// [`PendingReduction::finish`] waits for it.
///
/// It owns its buffers, so nothing the caller does can free or change memory MPI still
/// reads or writes. Dropping it without `finish` waits for completion.
pub struct PendingReduction<'d> {
    buffers: ReductionBuffers<'d>,
    combine: Combine,
    /// This rank, the ranks and the values per rank.
    rank: usize,
    ranks: usize,
    len: usize,
    exchange: bool,
    // Ties the reduction to the Domain (MPI must outlive it) and keeps it on its thread.
    _domain: PhantomData<&'d Domain>,
}

impl Domain {
    /// Starts the element-wise `combine` over ranks of `values` and returns without
    /// waiting; the values are copied, so the caller may change `values` meanwhile.
    /// `tag` (`0..=Exchange::MAX_TAG`) keeps its messages apart from any other exchange
    /// in flight.
    ///
    /// All ranks must call, with slices of the same length, in the same order as their
    /// other collectives.
    ///
    /// # Panics
    /// Above 2³¹−1 values.
    pub fn start_reduction<'d>(
        &'d self,
        values: &[f64],
        combine: Combine,
        tag: i32,
        mut buffers: ReductionBuffers<'d>,
    ) -> PendingReduction<'d> {
        buffers.wait_for_sends();
        let (rank, ranks, len) = (self.rank(), self.size(), values.len());
        let exchange = ranks <= EXCHANGE_RANKS_MAX;
        let mut pending = PendingReduction {
            buffers,
            combine,
            rank,
            ranks,
            len,
            exchange,
            _domain: PhantomData,
        };
        let b = &mut pending.buffers;
        b.receives.clear();
        b.send.clear();
        b.send.extend_from_slice(values);
        b.recv.clear();
        b.recv.resize(if exchange { len * ranks } else { len }, 0.0);
        let count = to_count(len);
        let comm = self.raw_comm();
        // SAFETY (all calls below): both buffers are heap allocations owned by `pending`,
        // not resized or moved out until their requests have completed (finish or Drop
        // waits for the receives, the buffers' next start or Drop for the sends); moving
        // `pending` does not move their heap data. Each receive writes its own rank's
        // `len` values of `recv`; datatypes, operation and counts match.
        unsafe {
            let null = mpi::ffi::RSMPI_REQUEST_NULL;
            let double = mpi::ffi::RSMPI_DOUBLE;
            if !exchange {
                let op = match combine {
                    Combine::Sum => mpi::ffi::RSMPI_SUM,
                    Combine::Max => mpi::ffi::RSMPI_MAX,
                };
                let mut request = null;
                mpi::ffi::MPI_Iallreduce(
                    b.send.as_ptr() as *const c_void,
                    b.recv.as_mut_ptr() as *mut c_void,
                    count,
                    double,
                    op,
                    comm,
                    &mut request,
                );
                b.receives.push(request);
                return pending;
            }
            for other in (0..ranks).filter(|&r| r != rank) {
                let mut request = null;
                mpi::ffi::MPI_Irecv(
                    b.recv[other * len..].as_mut_ptr() as *mut c_void,
                    count,
                    double,
                    other as i32,
                    tag,
                    comm,
                    &mut request,
                );
                b.receives.push(request);
            }
            for other in (0..ranks).filter(|&r| r != rank) {
                let mut request = null;
                mpi::ffi::MPI_Isend(
                    b.send.as_ptr() as *const c_void,
                    count,
                    double,
                    other as i32,
                    tag,
                    comm,
                    &mut request,
                );
                b.sends.push(request);
            }
        }
        pending
    }
}

impl<'d> PendingReduction<'d> {
    /// Waits for the reduction, writes it into `values` (the length given to the start)
    /// and returns the buffers for the next one.
    ///
    /// # Panics
    /// When `values` has another length than the reduction.
    pub fn finish(mut self, values: &mut [f64]) -> ReductionBuffers<'d> {
        assert_eq!(
            values.len(),
            self.len,
            "a reduction finished with another length"
        );
        wait_all(&mut self.buffers.receives);
        let b = &self.buffers;
        if !self.exchange {
            values.copy_from_slice(&b.recv);
        } else {
            let from = |r: usize| {
                if r == self.rank {
                    &b.send[..]
                } else {
                    &b.recv[r * self.len..(r + 1) * self.len]
                }
            };
            values.copy_from_slice(from(0));
            for r in 1..self.ranks {
                let theirs = from(r);
                match self.combine {
                    Combine::Sum => (values.iter_mut().zip(theirs)).for_each(|(v, t)| *v += t),
                    Combine::Max => (values.iter_mut().zip(theirs)).for_each(|(v, t)| {
                        *v = v.max(*t);
                    }),
                }
            }
        }
        std::mem::take(&mut self.buffers)
    }

    /// Waits for the reduction and drops its result (a caller that no longer needs it:
    /// every rank must still have started it); returns the buffers.
    pub fn discard(mut self) -> ReductionBuffers<'d> {
        wait_all(&mut self.buffers.receives);
        std::mem::take(&mut self.buffers)
    }
}

impl Drop for PendingReduction<'_> {
    fn drop(&mut self) {
        // MPI may still write the receive buffer: wait first.
        wait_all(&mut self.buffers.receives);
    }
}

/// `MPI_Waitall` on `requests` (completed and null ones included); leaves them null.
fn wait_all(requests: &mut [mpi::ffi::MPI_Request]) {
    if requests.is_empty() {
        return;
    }
    // SAFETY: every request is live or null; MPI_STATUSES_IGNORE is MPI's own constant.
    unsafe {
        mpi::ffi::MPI_Waitall(
            requests.len() as i32,
            requests.as_mut_ptr(),
            mpi::ffi::RSMPI_STATUSES_IGNORE,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::Combine;
    use crate::domain::with_test_domain;

    #[test]
    fn a_reduction_started_then_finished_is_the_blocking_one_and_keeps_its_buffers() {
        with_test_domain(|d| {
            let values = [1.5, -2.0, 0.0, 7.25];
            let (mut sum, mut max) = (values, values);
            d.sum_in_place(&mut sum);
            d.max_in_place(&mut max);
            let mut buffers = Default::default();
            for (combine, blocking) in [(Combine::Sum, sum), (Combine::Max, max)] {
                for _ in 0..2 {
                    let mut caller = values;
                    let pending = d.start_reduction(&caller, combine, 7, buffers);
                    // the caller's slice is free while the reduction is in flight
                    caller = [9.0; 4];
                    assert_eq!(caller, [9.0; 4]);
                    buffers = pending.finish(&mut caller);
                    assert_eq!(caller, blocking);
                }
            }
            // discarded, or dropped unfinished: waits, and leaks no request into the next
            buffers = d
                .start_reduction(&values, Combine::Sum, 7, buffers)
                .discard();
            drop(d.start_reduction(&values, Combine::Max, 7, buffers));
            let mut again = values;
            d.sum_in_place(&mut again);
            assert_eq!(again, sum);
        });
    }
}
