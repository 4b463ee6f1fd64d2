//! Domain decomposition and the one place in mufe that talks to MPI.
//!
//! Every MPI call of the program goes through [`Domain`] (and the [`Exchange`] helper built
//! on it); no other module imports `mpi`. The only other MPI user is HDF5's MPI-IO driver,
//! which receives the communicator from [`Domain::raw_comm`]. Keeping MPI here keeps the
//! rest of the code free of `#[cfg]`s and makes the serial path (one rank, started without
//! `mpirun`) the same code as the parallel one: with one rank every collective is a cheap
//! no-op or a copy.
//!
//! # Threads
//! MPI is initialised with `MPI_THREAD_FUNNELED`: rayon worker threads compute, only the
//! thread that created the `Domain` communicates. `Domain` is deliberately neither `Send`
//! nor `Sync`, so it cannot be captured by a rayon closure or moved to another thread: the
//! funnelled contract is checked by the compiler.
//!
//! # Collectives
//! A method documented "all ranks must call" is collective: every rank of the job must call
//! it, in the same order relative to the other collectives, with compatible arguments
//! (same lengths where said). A rank that skips one deadlocks the job.
//!
//! # Failure
//! With more than one rank, [`Domain::init`] installs a panic hook that prints the panic
//! prefixed with `rank R:` and then calls `MPI_Abort`, so a panic on one rank ends the whole
//! job within seconds instead of leaving the other ranks waiting forever in a collective.

pub mod halo;
mod pending_reduction;

pub use pending_reduction::{Combine, PendingReduction, ReductionBuffers, EXCHANGE_RANKS_MAX};

use std::cell::RefCell;
use std::marker::PhantomData;
use std::os::raw::{c_int, c_void};

use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::{Count, Threading};

use crate::error::MufeError;

/// Rank 0 holds the root role in every rooted collective (gather, broadcast, file metadata).
const ROOT: i32 = 0;

/// Largest element count of one MPI message: MPI counts are C `int`s.
const MAX_COUNT: usize = i32::MAX as usize;

/// Whether an MPI launcher (`mpirun`, `mpiexec`, `srun` through PMI) started this process,
/// read from the variables Open MPI, MPICH and PMIx set in each rank; MPI itself need not
/// be initialised. Such a rank does not start processes of its own, and its stdout is not
/// a user's terminal even when `isatty` says so: Open MPI gives each rank a
/// pseudo-terminal whatever the job's output goes to.
pub fn launched_by_mpi_launcher() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"]
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}

/// This process's view of the MPI job: its rank, the number of ranks, and the collectives
/// the simulation needs. Create exactly one, at the start of `main`, with [`Domain::init`];
/// MPI is finalised when it is dropped, after which MPI cannot be used again in the process
/// (so everything that uses MPI or MPI-IO, such as a results writer, must be dropped first —
/// borrowing the `Domain` enforces that).
pub struct Domain {
    world: SimpleCommunicator,
    rank: usize,
    size: usize,
    threading: Threading,
    /// The send side of all-reduces, kept between calls (rsmpi has no in-place mode): the
    /// step's per-grain reductions then allocate nothing.
    reduce_send: RefCell<Vec<f64>>,
    // Declared last so it is dropped last: dropping the Universe calls MPI_Finalize.
    _universe: Universe,
    // Raw-pointer marker: keeps `Domain` !Send and !Sync on every MPI implementation (the
    // funnelled threading level forbids MPI calls from other threads).
    _funneled: PhantomData<*const ()>,
}

impl Domain {
    /// Initialises MPI (`MPI_Init_thread` with `MPI_THREAD_FUNNELED`) and returns this
    /// process's domain. Works with and without `mpirun` (a binary started directly is a
    /// singleton job of size 1).
    ///
    /// All ranks must call (MPI initialisation is collective over the job).
    ///
    /// # Panics
    /// If MPI was already initialised in this process (a second `Domain`, or MPI used by
    /// other code): MPI can be initialised once per process, so this is a programming
    /// error. Use [`Domain::try_init`] to get an error instead.
    pub fn init() -> Domain {
        match Domain::try_init() {
            Ok(domain) => domain,
            Err(e) => panic!("{e}"),
        }
    }

    /// Like [`Domain::init`], but returns an error instead of panicking when MPI was
    /// already initialised (or finalised) in this process.
    ///
    /// All ranks must call.
    pub fn try_init() -> Result<Domain, MufeError> {
        Domain::init_with(Threading::Funneled)
    }

    fn init_with(requested: Threading) -> Result<Domain, MufeError> {
        let Some((universe, provided)) = mpi::initialize_with_threading(requested) else {
            return Err(MufeError::Run(
                "MPI: already initialised in this process; create exactly one Domain per \
                 process (Domain::init at the start of main)"
                    .to_string(),
            ));
        };
        let world = universe.world();
        // Ranks and sizes are non-negative C ints.
        let rank = usize::try_from(world.rank()).unwrap_or(0);
        let size = usize::try_from(world.size()).unwrap_or(1);
        if size > 1 {
            install_abort_hook(rank);
        }
        Ok(Domain {
            world,
            rank,
            size,
            threading: provided,
            reduce_send: RefCell::new(Vec::new()),
            _universe: universe,
            _funneled: PhantomData,
        })
    }

    /// This process's rank, `0..size()`.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Number of ranks in the job (1 when started without `mpirun`).
    pub fn size(&self) -> usize {
        self.size
    }

    /// Whether this is rank 0, the root of rooted collectives and the rank that writes
    /// whole-job data (history, scene) and prints.
    pub fn is_root(&self) -> bool {
        self.rank == 0
    }

    /// Thread support the MPI library actually provided. mufe asks for `Funneled`; a library
    /// that only gives `Single` still works in practice (rayon threads never call MPI), but
    /// the CLI may want to say so.
    pub fn threading(&self) -> Threading {
        self.threading
    }

    /// Name of the node this rank runs on (`MPI_Get_processor_name`, usually the hostname).
    /// Local, not collective.
    pub fn processor_name(&self) -> String {
        mpi::environment::processor_name().unwrap_or_else(|_| "unknown".to_string())
    }

    /// Blocks until every rank has reached it.
    ///
    /// All ranks must call.
    pub fn barrier(&self) {
        self.world.barrier();
    }

    /// Element-wise sum over ranks, result on every rank (`MPI_Allreduce`, `MPI_SUM`).
    ///
    /// All ranks must call, with slices of the same length.
    pub fn sum_in_place(&self, values: &mut [f64]) {
        self.all_reduce_f64(values, SystemOperation::sum());
    }

    /// Element-wise maximum over ranks, result on every rank.
    ///
    /// All ranks must call, with slices of the same length.
    pub fn max_in_place(&self, values: &mut [f64]) {
        self.all_reduce_f64(values, SystemOperation::max());
    }

    /// Element-wise minimum over ranks, result on every rank (e.g. the stable Δt).
    ///
    /// All ranks must call, with slices of the same length.
    pub fn min_in_place(&self, values: &mut [f64]) {
        self.all_reduce_f64(values, SystemOperation::min());
    }

    fn all_reduce_f64(&self, values: &mut [f64], op: SystemOperation) {
        // Serial path: the sum/max/min over one rank is the value itself.
        if self.size == 1 {
            return;
        }
        let mut send = self.reduce_send.borrow_mut();
        send.clear();
        send.extend_from_slice(values);
        self.world.all_reduce_into(&send[..], values, op);
    }

    /// Sum of one `u64` over ranks, result on every rank (global counts of nodes, elements).
    ///
    /// All ranks must call.
    pub fn sum_u64(&self, local: u64) -> u64 {
        if self.size == 1 {
            return local;
        }
        let mut total = 0u64;
        self.world
            .all_reduce_into(&local, &mut total, SystemOperation::sum());
        total
    }

    /// Exclusive prefix sum over ranks in rank order: returns `(offset, total)` where
    /// `offset` is the sum of `local` over the ranks before this one (0 on rank 0) and
    /// `total` the sum over all ranks. This is how each rank finds where its rows go in a
    /// global array (mesh nodes, field rows in results.h5).
    ///
    /// All ranks must call.
    pub fn exclusive_scan_u64(&self, local: u64) -> (u64, u64) {
        // One all-gather gives both numbers exactly (MPI_Exscan leaves rank 0 undefined and
        // would need a second collective for the total); P values are tiny.
        let all = self.all_gather_u64(local);
        let offset = all[..self.rank].iter().sum();
        let total = all.iter().sum();
        (offset, total)
    }

    /// Every rank's `value`, indexed by rank, on every rank.
    ///
    /// All ranks must call.
    pub fn all_gather_u64(&self, value: u64) -> Vec<u64> {
        let mut all = vec![0u64; self.size];
        if self.size == 1 {
            all[0] = value;
        } else {
            self.world.all_gather_into(&value, &mut all[..]);
        }
        all
    }

    /// Personalised all-to-all of one count per rank: `send[q]` goes to rank q, and the
    /// result's entry p is what rank p sent here (used to size migration messages).
    ///
    /// All ranks must call, with `send.len()` equal to the number of ranks.
    pub fn all_to_all_u64(&self, send: &[u64]) -> Vec<u64> {
        assert_eq!(send.len(), self.size, "all_to_all_u64: one count per rank");
        let mut recv = vec![0u64; self.size];
        if self.size == 1 {
            recv[0] = send[0];
        } else {
            self.world.all_to_all_into(send, &mut recv[..]);
        }
        recv
    }

    /// Replaces `root_bytes` on every rank by rank 0's bytes (length sent first, so other
    /// ranks may pass any vector, e.g. an empty one). Used to make every rank use the same
    /// scene text, provenance and restart data.
    ///
    /// All ranks must call.
    pub fn broadcast_bytes(&self, root_bytes: &mut Vec<u8>) {
        if self.size == 1 {
            return;
        }
        let root = self.world.process_at_rank(ROOT);
        let mut len = root_bytes.len() as u64;
        root.broadcast_into(&mut len);
        let len = usize::try_from(len).unwrap_or(usize::MAX);
        root_bytes.resize(len, 0);
        // MPI counts are C ints: send big payloads (checkpoints) in pieces.
        for piece in root_bytes.chunks_mut(MAX_COUNT) {
            root.broadcast_into(piece);
        }
    }

    /// Concatenation of every rank's `local` slice, in rank order, on rank 0 (`Some`); other
    /// ranks get `None`. Slices may have different lengths.
    ///
    /// All ranks must call.
    ///
    /// # Panics
    /// If the concatenation exceeds 2³¹−1 values (an MPI count limit; bulk data belongs in
    /// results.h5, written collectively, not gathered).
    pub fn gather_f64_to_root(&self, local: &[f64]) -> Option<Vec<f64>> {
        if self.size == 1 {
            return Some(local.to_vec());
        }
        let root = self.world.process_at_rank(ROOT);
        let count = to_count(local.len());
        if self.is_root() {
            let mut counts: Vec<Count> = vec![0; self.size];
            root.gather_into_root(&count, &mut counts[..]);
            let mut displs: Vec<Count> = Vec::with_capacity(self.size);
            let mut total = 0usize;
            for &c in &counts {
                displs.push(to_count(total));
                total += usize::try_from(c).unwrap_or(0);
            }
            let mut all = vec![0.0f64; total];
            {
                let mut partition = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
                root.gather_varcount_into_root(local, &mut partition);
            }
            Some(all)
        } else {
            root.gather_into(&count);
            root.gather_varcount_into(local);
            None
        }
    }

    /// Ends the whole job with exit code `code` (`MPI_Abort` on the world communicator).
    /// Not collective: one rank may call it alone, which is its purpose.
    pub fn abort(&self, code: i32) -> ! {
        self.world.abort(code)
    }

    /// The world communicator as a raw handle, for HDF5's MPI-IO file driver (which
    /// duplicates it). Nothing else should use it.
    pub fn raw_comm(&self) -> mpi::ffi::MPI_Comm {
        self.world.as_raw()
    }
}

/// Converts a length to an MPI count.
///
/// # Panics
/// Above 2³¹−1 elements (see the callers' docs).
fn to_count(n: usize) -> Count {
    Count::try_from(n)
        .unwrap_or_else(|_| panic!("MPI message of {n} elements exceeds the MPI count limit"))
}

/// Installs the panic hook that turns a panic on one rank into the end of the job.
fn install_abort_hook(rank: usize) {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = if let Some(s) = payload.downcast_ref::<&str>() {
            (*s).to_string()
        } else if let Some(s) = payload.downcast_ref::<String>() {
            s.clone()
        } else {
            "(non-string panic payload)".to_string()
        };
        let location = info
            .location()
            .map(|l| format!(" at {}:{}:{}", l.file(), l.line(), l.column()))
            .unwrap_or_default();
        crate::error::report_line(format_args!("rank {rank}: panicked{location}: {message}"));
        // The default hook adds the thread name and the backtrace hint.
        previous(info);
        // After MPI_Finalize (Domain dropped) an abort is neither allowed nor needed: the
        // other ranks are no longer waiting on this one in a collective.
        if mpi::environment::is_initialized() && !mpi::environment::is_finalized() {
            // A panic may come from a rayon worker; MPI_Abort from a non-main thread is
            // outside the funnelled contract but is the only way to stop the other ranks,
            // and OpenMPI and MPICH both honour it.
            unsafe {
                mpi::ffi::MPI_Abort(mpi::ffi::RSMPI_COMM_WORLD, 1);
            }
            std::process::abort();
        }
    }));
}

/// A reusable point-to-point exchange of `f64` buffers between ranks with begin/end halves
/// (MFEM's `GroupCommunicator::BcastBegin/End` pattern), so that communication can overlap
/// computation: `begin` posts non-blocking receives and sends and returns at once, `end`
/// waits and hands over the received buffers. Halo exchange of ghost surface data is built
/// on this.
///
/// Both sides must agree on the pattern: for every `(to, data)` a rank sends, rank `to`
/// lists `(from, data.len())` in its receive counts, with the same tag. Messages between
/// the same two ranks with the same tag arrive in the order they were sent. A rank may send
/// to itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Exchange {
    tag: i32,
}

/// An exchange in flight, returned by [`Exchange::begin`]; pass it to [`Exchange::end`].
///
/// It owns the send and receive buffers, so nothing the caller does can free or change
/// memory MPI is still reading or writing. Dropping it without `end` waits for completion
/// (the buffers must outlive the requests); forgetting it only leaks the buffers.
pub struct PendingExchange<'d> {
    buffers: ExchangeBuffers,
    n_recv: usize,
    tag: i32,
    /// The receives have completed and their lengths were checked
    /// ([`Exchange::end_receives`]): only the sends may still be in flight.
    received: bool,
    done: bool,
    // Ties the exchange to the Domain (MPI must outlive it) and keeps it on its thread.
    _domain: PhantomData<&'d Domain>,
}

/// Everything an exchange allocates, kept by a caller that exchanges every step (the halo)
/// and handed to [`Exchange::begin_reusing`] again, so that a step allocates nothing once
/// the buffers have grown to the pattern's size.
#[derive(Default)]
pub struct ExchangeBuffers {
    /// The messages sent, back to back in the order of the send counts.
    pub send: Vec<f64>,
    /// The messages received, back to back in the order of the receive counts.
    pub recv: Vec<f64>,
    /// Receive requests first (one per receive), then send requests.
    requests: Vec<mpi::ffi::MPI_Request>,
    /// `(from rank, start in recv, count)` per receive, in the order given to `begin`.
    recvs: Vec<(usize, usize, usize)>,
    statuses: Vec<mpi::ffi::MPI_Status>,
}

impl Exchange {
    /// Largest tag every MPI implementation accepts (`MPI_TAG_UB` ≥ 32767).
    pub const MAX_TAG: i32 = 32767;

    /// An exchange using message tag `tag` (`0..=MAX_TAG`). Use different tags for
    /// exchanges that can be in flight at the same time (e.g. forward and reverse halo).
    pub fn new(tag: i32) -> Self {
        Exchange { tag }
    }

    /// The message tag.
    pub fn tag(&self) -> i32 {
        self.tag
    }

    /// Posts the receives (`recv_counts`: `(from rank, number of f64)`) and the sends
    /// (`sends`: `(to rank, data)`, data copied into the exchange) and returns without
    /// waiting.
    ///
    /// Not collective: only ranks that exchange with each other must call, with matching
    /// patterns. Returns an error, before posting anything, for a rank outside the job, a
    /// tag outside `0..=MAX_TAG` or a message too large for MPI; a rank that gets an error
    /// should [`Domain::abort`] because its partners will wait for it.
    pub fn begin<'d>(
        &self,
        domain: &'d Domain,
        sends: &[(usize, Vec<f64>)],
        recv_counts: &[(usize, usize)],
    ) -> Result<PendingExchange<'d>, MufeError> {
        let mut buffers = ExchangeBuffers::default();
        let send_counts: Vec<(usize, usize)> = sends.iter().map(|(r, d)| (*r, d.len())).collect();
        for (_, data) in sends {
            buffers.send.extend_from_slice(data);
        }
        self.begin_reusing(domain, buffers, &send_counts, recv_counts)
    }

    /// [`Exchange::begin`] with the caller's buffers: `buffers.send` holds the messages back
    /// to back in the order of `send_counts` (`(to rank, number of f64)`); the receive
    /// buffer and the request lists are resized in place. [`Exchange::end_reusing`] gives
    /// the buffers back.
    pub fn begin_reusing<'d>(
        &self,
        domain: &'d Domain,
        mut buffers: ExchangeBuffers,
        send_counts: &[(usize, usize)],
        recv_counts: &[(usize, usize)],
    ) -> Result<PendingExchange<'d>, MufeError> {
        if !(0..=Self::MAX_TAG).contains(&self.tag) {
            return Err(MufeError::Run(format!(
                "exchange: tag {} outside 0..={}",
                self.tag,
                Self::MAX_TAG
            )));
        }
        let bad_rank = send_counts
            .iter()
            .chain(recv_counts)
            .map(|(r, _)| *r)
            .find(|&r| r >= domain.size);
        if let Some(r) = bad_rank {
            return Err(MufeError::Run(format!(
                "exchange: rank {r} does not exist (job has {} ranks)",
                domain.size
            )));
        }
        let too_big = send_counts
            .iter()
            .chain(recv_counts)
            .map(|(_, n)| *n)
            .find(|&n| n > MAX_COUNT);
        if let Some(n) = too_big {
            return Err(MufeError::Run(format!(
                "exchange: message of {n} values exceeds the MPI count limit"
            )));
        }
        let sent: usize = send_counts.iter().map(|(_, n)| n).sum();
        if sent != buffers.send.len() {
            return Err(MufeError::Run(format!(
                "exchange: send counts add up to {sent} values, the buffer holds {}",
                buffers.send.len()
            )));
        }

        buffers.recvs.clear();
        let mut start = 0usize;
        for &(from, count) in recv_counts {
            buffers.recvs.push((from, start, count));
            start += count;
        }
        buffers.recv.clear();
        buffers.recv.resize(start, 0.0);
        buffers.requests.clear();
        let mut pending = PendingExchange {
            n_recv: buffers.recvs.len(),
            buffers,
            tag: self.tag,
            received: false,
            done: false,
            _domain: PhantomData,
        };
        let comm = domain.raw_comm();
        let b = &mut pending.buffers;
        // SAFETY: the buffers are heap allocations owned by `pending`; they are never
        // resized or moved out until every request has completed (end or Drop waits), and
        // moving `pending` itself does not move the heap data. Ranks and counts were checked
        // above. Receives are posted before sends so that self-sends and eager messages
        // find a posted receive.
        unsafe {
            let dtype = mpi::ffi::RSMPI_DOUBLE;
            let base = b.recv.as_mut_ptr();
            for &(from, start, count) in &b.recvs {
                let mut req = mpi::ffi::RSMPI_REQUEST_NULL;
                mpi::ffi::MPI_Irecv(
                    base.add(start) as *mut c_void,
                    count as c_int,
                    dtype,
                    from as c_int,
                    self.tag,
                    comm,
                    &mut req,
                );
                b.requests.push(req);
            }
            let base = b.send.as_ptr();
            let mut start = 0usize;
            for &(to, count) in send_counts {
                let mut req = mpi::ffi::RSMPI_REQUEST_NULL;
                mpi::ffi::MPI_Isend(
                    base.add(start) as *const c_void,
                    count as c_int,
                    dtype,
                    to as c_int,
                    self.tag,
                    comm,
                    &mut req,
                );
                b.requests.push(req);
                start += count;
            }
        }
        Ok(pending)
    }

    /// Waits for every receive and send of `pending` and returns the received buffers as
    /// `(from rank, data)`, in the order of `recv_counts` given to `begin`.
    ///
    /// Returns an error if a message was shorter than its announced count (a pattern
    /// mismatch between the two ranks). A longer message is an MPI truncation error, which
    /// aborts the job.
    pub fn end(&self, pending: PendingExchange<'_>) -> Result<Vec<(usize, Vec<f64>)>, MufeError> {
        let buffers = self.end_reusing(pending)?;
        Ok(buffers
            .received()
            .map(|(from, data)| (from, data.to_vec()))
            .collect())
    }

    /// Waits for the receives of `pending` only and checks their lengths; the received
    /// messages are then `pending.received()`, while its sends may still be in flight.
    /// [`Exchange::end_reusing`] completes them later and gives the buffers back.
    ///
    /// Why: a send completes only once its receiver has entered MPI to take the message
    /// (Open MPI's shared-memory transport copies a large message on the receiver's side and
    /// acknowledges it), so a step that waited for its own sends with its receives waited
    /// for the slowest neighbour to reach the same point of its step: one more lock-step
    /// point per step (docs/BENCHMARKS.md, session 63).
    pub fn end_receives(&self, pending: &mut PendingExchange<'_>) -> Result<(), MufeError> {
        if pending.received {
            return Ok(());
        }
        // receive requests come first
        pending.wait_requests(0..pending.n_recv);
        pending.received = true;
        let b = &pending.buffers;
        for (i, &(from, _, count)) in b.recvs.iter().enumerate() {
            let mut got: c_int = 0;
            // SAFETY: the status was filled by MPI_Waitall for this completed receive.
            unsafe {
                mpi::ffi::MPI_Get_count(&b.statuses[i], mpi::ffi::RSMPI_DOUBLE, &mut got);
            }
            if usize::try_from(got).ok() != Some(count) {
                return Err(MufeError::Run(format!(
                    "exchange (tag {}): expected {count} values from rank {from}, got {got}",
                    pending.tag
                )));
            }
        }
        Ok(())
    }

    /// [`Exchange::end`] without copies: waits, checks every receive's length and gives the
    /// buffers back ([`ExchangeBuffers::received`] lists the messages).
    pub fn end_reusing(
        &self,
        mut pending: PendingExchange<'_>,
    ) -> Result<ExchangeBuffers, MufeError> {
        self.end_receives(&mut pending)?;
        pending.wait_all();
        Ok(std::mem::take(&mut pending.buffers))
    }
}

impl ExchangeBuffers {
    /// The messages of the last exchange as `(from rank, data)`, in the order of the
    /// receive counts.
    pub fn received(&self) -> impl Iterator<Item = (usize, &[f64])> {
        self.recvs
            .iter()
            .map(|&(from, start, count)| (from, &self.recv[start..start + count]))
    }
}

impl PendingExchange<'_> {
    /// Number of receives still to be handed over.
    pub fn receives(&self) -> usize {
        self.n_recv
    }

    /// The messages received, once [`Exchange::end_receives`] has returned.
    pub fn received(&self) -> impl Iterator<Item = (usize, &[f64])> {
        debug_assert!(self.received, "the receives have not been waited for");
        self.buffers.received()
    }

    /// Completes every request still open (the sends only, once the receives have been
    /// waited); the statuses (receives first) are left in the buffers.
    fn wait_all(&mut self) {
        let first = if self.received { self.n_recv } else { 0 };
        self.wait_requests(first..self.buffers.requests.len());
        self.done = true;
    }

    /// Waits for the requests `range` (receives first, then sends), their statuses at the
    /// same places; a range from 0 starts the statuses afresh.
    fn wait_requests(&mut self, range: std::ops::Range<usize>) {
        let b = &mut self.buffers;
        if range.start == 0 {
            b.statuses.clear();
        }
        // SAFETY: MPI_Status is a plain C struct; zeroed is a valid value and MPI overwrites
        // it. The requests are live (or already MPI_REQUEST_NULL, which Waitall accepts).
        b.statuses
            .resize(b.requests.len(), unsafe { std::mem::zeroed() });
        if !self.done && !range.is_empty() {
            unsafe {
                mpi::ffi::MPI_Waitall(
                    range.len() as c_int,
                    b.requests.as_mut_ptr().add(range.start),
                    b.statuses.as_mut_ptr().add(range.start),
                );
            }
        }
    }
}

impl Drop for PendingExchange<'_> {
    fn drop(&mut self) {
        // MPI may still be writing into recv_buf / reading send_buf: wait before freeing.
        if !self.done {
            self.wait_all();
        }
    }
}

/// Runs `f` with the process-wide test domain (size 1, singleton MPI). MPI can be
/// initialised once per process, and libtest runs tests on several threads, so unit tests
/// share one Domain initialised with `MPI_THREAD_SERIALIZED` behind a mutex (never
/// finalised, which a singleton job tolerates).
#[cfg(test)]
pub(crate) fn with_test_domain<R>(f: impl FnOnce(&Domain) -> R) -> R {
    use std::sync::{Mutex, OnceLock};
    struct Shared(Domain);
    // SAFETY: MPI was initialised with MPI_THREAD_SERIALIZED and the Domain is only reached
    // through the mutex, so no two threads call MPI at the same time.
    unsafe impl Send for Shared {}
    static SHARED: OnceLock<Mutex<Shared>> = OnceLock::new();
    let shared = SHARED.get_or_init(|| {
        let domain =
            Domain::init_with(Threading::Serialized).unwrap_or_else(|e| panic!("test domain: {e}"));
        Mutex::new(Shared(domain))
    });
    let guard = shared.lock().unwrap_or_else(|p| p.into_inner());
    f(&guard.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_rank_collectives_are_identities() {
        with_test_domain(|d| {
            assert_eq!(d.size(), 1);
            assert_eq!(d.rank(), 0);
            assert!(d.is_root());
            d.barrier();
            let mut v = [1.5, -2.0, 3.0];
            d.sum_in_place(&mut v);
            assert_eq!(v, [1.5, -2.0, 3.0]);
            d.max_in_place(&mut v);
            d.min_in_place(&mut v);
            assert_eq!(v, [1.5, -2.0, 3.0]);
            assert_eq!(d.sum_u64(7), 7);
            assert_eq!(d.exclusive_scan_u64(5), (0, 5));
            assert_eq!(d.all_gather_u64(9), vec![9]);
            let mut bytes = b"scene".to_vec();
            d.broadcast_bytes(&mut bytes);
            assert_eq!(bytes, b"scene");
            assert_eq!(d.gather_f64_to_root(&[1.0, 2.0]), Some(vec![1.0, 2.0]));
            assert!(!d.processor_name().is_empty());
        });
    }

    #[test]
    fn second_init_is_an_error_not_a_crash() {
        with_test_domain(|_| {
            let again = Domain::try_init();
            assert!(
                matches!(again, Err(MufeError::Run(ref m)) if m.contains("already initialised"))
            );
        });
    }

    #[test]
    fn exchange_with_self_round_trips() {
        with_test_domain(|d| {
            let ex = Exchange::new(11);
            let sends = vec![(0usize, vec![1.0, 2.0, 3.0]), (0usize, vec![4.0])];
            let pending = ex.begin(d, &sends, &[(0, 3), (0, 1)]).unwrap();
            assert_eq!(pending.receives(), 2);
            let got = ex.end(pending).unwrap();
            assert_eq!(got, vec![(0, vec![1.0, 2.0, 3.0]), (0, vec![4.0])]);
        });
    }

    #[test]
    fn exchange_rejects_bad_pattern_before_posting() {
        with_test_domain(|d| {
            let ex = Exchange::new(12);
            assert!(ex.begin(d, &[(1, vec![1.0])], &[]).is_err());
            assert!(ex.begin(d, &[], &[(3, 1)]).is_err());
            assert!(Exchange::new(-1).begin(d, &[], &[]).is_err());
            // A shorter message than announced is reported, not silently accepted.
            let pending = ex.begin(d, &[(0, vec![1.0])], &[(0, 2)]).unwrap();
            assert!(ex.end(pending).is_err());
        });
    }

    #[test]
    fn dropped_exchange_completes() {
        with_test_domain(|d| {
            let ex = Exchange::new(13);
            let pending = ex.begin(d, &[(0, vec![5.0; 100])], &[(0, 100)]).unwrap();
            drop(pending);
            d.barrier();
        });
    }
}
