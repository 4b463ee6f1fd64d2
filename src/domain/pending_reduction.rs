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

use std::os::raw::c_void;

use super::{to_count, Domain, Exchange, ExchangeBuffers, PendingExchange};

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
/// It also holds the last exchange, whose sends complete when their receivers take them:
/// the next start waits for them, not the finish ([`Exchange::end_receives`]).
#[derive(Default)]
pub struct ReductionBuffers<'d> {
    /// This rank's values; `MPI_Iallreduce` also sends from here.
    own: Vec<f64>,
    /// `MPI_Iallreduce`'s result.
    recv: Vec<f64>,
    /// The exchange's buffers, or the last exchange with its sends still in flight.
    exchange: ExchangeBuffers,
    sending: Option<PendingExchange<'d>>,
    /// `(rank, values)` of every other rank: the exchange's send and receive counts.
    counts: Vec<(usize, usize)>,
}

/// A reduction in flight, returned by [`Domain::start_reduction`];
/// [`PendingReduction::finish`] waits for it.
///
/// It owns its buffers, so nothing the caller does can free or change memory MPI still
/// reads or writes. Dropping it without `finish` waits for completion.
pub struct PendingReduction<'d> {
    buffers: ReductionBuffers<'d>,
    combine: Combine,
    tag: i32,
    rank: usize,
    in_flight: Option<InFlight<'d>>,
}

enum InFlight<'d> {
    Exchange(PendingExchange<'d>),
    Allreduce(mpi::ffi::MPI_Request),
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
    /// Above 2³¹−1 values, or for a tag outside `0..=Exchange::MAX_TAG`.
    pub fn start_reduction<'d>(
        &'d self,
        values: &[f64],
        combine: Combine,
        tag: i32,
        mut buffers: ReductionBuffers<'d>,
    ) -> PendingReduction<'d> {
        let (rank, ranks) = (self.rank(), self.size());
        let exchange = Exchange::new(tag);
        let mut sent = match buffers.sending.take() {
            Some(last) => (exchange.end_reusing(last)).expect("every rank reduces alike"),
            None => std::mem::take(&mut buffers.exchange),
        };
        buffers.own.clear();
        buffers.own.extend_from_slice(values);
        let in_flight = if ranks <= EXCHANGE_RANKS_MAX {
            let counts = &mut buffers.counts;
            counts.clear();
            counts.extend((0..ranks).filter(|&r| r != rank).map(|r| (r, values.len())));
            sent.send.clear();
            counts
                .iter()
                .for_each(|_| sent.send.extend_from_slice(values));
            let pending = exchange.begin_reusing(self, sent, &counts[..], &counts[..]);
            InFlight::Exchange(pending.unwrap_or_else(|e| panic!("reduction: {e}")))
        } else {
            buffers.exchange = sent;
            buffers.recv.clear();
            buffers.recv.resize(values.len(), 0.0);
            // SAFETY: both buffers are heap allocations owned by the pending reduction,
            // not resized or moved out until the request has completed (finish or Drop
            // waits); moving it does not move their heap data. Datatype, operation and
            // counts match.
            unsafe {
                let op = match combine {
                    Combine::Sum => mpi::ffi::RSMPI_SUM,
                    Combine::Max => mpi::ffi::RSMPI_MAX,
                };
                let mut request = mpi::ffi::RSMPI_REQUEST_NULL;
                mpi::ffi::MPI_Iallreduce(
                    buffers.own.as_ptr() as *const c_void,
                    buffers.recv.as_mut_ptr() as *mut c_void,
                    to_count(values.len()),
                    mpi::ffi::RSMPI_DOUBLE,
                    op,
                    self.raw_comm(),
                    &mut request,
                );
                InFlight::Allreduce(request)
            }
        };
        PendingReduction {
            buffers,
            combine,
            tag,
            rank,
            in_flight: Some(in_flight),
        }
    }
}

impl<'d> PendingReduction<'d> {
    /// Waits for the reduction, writes it into `values` (the length given to the start)
    /// and returns the buffers for the next one.
    ///
    /// # Panics
    /// When `values` has another length than the reduction.
    pub fn finish(mut self, values: &mut [f64]) -> ReductionBuffers<'d> {
        let b = &mut self.buffers;
        assert_eq!(
            values.len(),
            b.own.len(),
            "a reduction finished with another length"
        );
        match self.in_flight.take() {
            Some(InFlight::Exchange(mut pending)) => {
                let exchange = Exchange::new(self.tag);
                (exchange.end_receives(&mut pending)).expect("every rank reduces alike");
                let theirs = pending.received().map(|(_, data)| data);
                combine_in_rank_order(self.combine, values, (self.rank, &b.own), theirs);
                b.sending = Some(pending);
            }
            Some(InFlight::Allreduce(mut request)) => {
                wait(&mut request);
                values.copy_from_slice(&b.recv);
            }
            None => unreachable!("a reduction is finished once"),
        }
        std::mem::take(&mut self.buffers)
    }

    /// Waits for the reduction and drops its result (a caller that no longer needs it:
    /// every rank must still have started it); returns the buffers.
    pub fn discard(mut self) -> ReductionBuffers<'d> {
        match self.in_flight.take() {
            Some(InFlight::Exchange(pending)) => self.buffers.sending = Some(pending),
            Some(InFlight::Allreduce(mut request)) => wait(&mut request),
            None => {}
        }
        std::mem::take(&mut self.buffers)
    }
}

impl Drop for PendingReduction<'_> {
    fn drop(&mut self) {
        // MPI may still write the receive buffer: wait first (a pending exchange waits as
        // it drops).
        if let Some(InFlight::Allreduce(request)) = &mut self.in_flight {
            wait(request);
        }
    }
}

/// Writes into `values` every rank's values combined in rank order: `own` (this rank's,
/// at index `rank`) and `theirs` (the other ranks', in ascending rank order), so that every
/// rank combines the same numbers in the same order and gets the same bits.
fn combine_in_rank_order<'a>(
    combine: Combine,
    values: &mut [f64],
    (rank, own): (usize, &'a [f64]),
    mut theirs: impl Iterator<Item = &'a [f64]>,
) {
    let mut by_rank = (0..).map_while(|r| if r == rank { Some(own) } else { theirs.next() });
    values.copy_from_slice(by_rank.next().expect("at least this rank's values"));
    for from in by_rank {
        let pairs = values.iter_mut().zip(from);
        match combine {
            Combine::Sum => pairs.for_each(|(v, t)| *v += t),
            Combine::Max => pairs.for_each(|(v, t)| *v = v.max(*t)),
        }
    }
}

/// `MPI_Wait` on a live or null request; leaves it null.
fn wait(request: &mut mpi::ffi::MPI_Request) {
    // SAFETY: the request is live or null; MPI_Status is a plain C struct, zeroed is valid
    // and MPI overwrites it.
    unsafe {
        let mut status: mpi::ffi::MPI_Status = std::mem::zeroed();
        mpi::ffi::MPI_Wait(request, &mut status);
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
