//! Collective MPI-IO writes of row blocks into HDF5 datasets.
//!
//! hdf5-metno's high-level writes use independent transfers (each rank writes on its own).
//! That is correct but does not let MPI-IO aggregate the ranks' pieces into large
//! contiguous writes, which is what makes parallel output scale. This module goes one level
//! down: a dataset-transfer property list with `H5FD_MPIO_COLLECTIVE`, each rank's selection
//! (one or more blocks of rows `[offset, offset + rows)`, the union of their hyperslabs),
//! one `H5Dwrite` per dataset, and a readback of the
//! I/O mode HDF5 actually used, so tests can prove the write really was collective.
//!
//! All unsafe HDF5 code of the results writer lives here, inside `hdf5::sync::sync` (the
//! hdf5 crate's global lock: the HDF5 library is not thread-safe).
//!
//! Every write here is collective: all ranks must call with the same dataset, in the same
//! order. A rank with nothing to write passes an empty slice; it still takes part (with an
//! empty selection), which MPI-IO requires. A rank whose arguments are invalid also still
//! takes part with an empty selection and then returns its error, so one rank's mistake
//! does not deadlock the others; callers should agree on success afterwards (the
//! `ResultsWriter` does).

use std::ffi::CString;
use std::os::raw::{c_int, c_void};

use hdf5::{Dataset, Group};
use hdf5_sys::h5::{herr_t, hsize_t};
use hdf5_sys::h5d::{H5Dcreate2, H5Dget_space, H5Dget_type, H5Dread, H5Dwrite};
use hdf5_sys::h5i::hid_t;
use hdf5_sys::h5p::{
    H5FD_mpio_xfer_t, H5Pclose, H5Pcreate, H5Pset_dxpl_mpio, H5P_CLS_DATASET_XFER, H5P_DEFAULT,
};
use hdf5_sys::h5s::{
    H5Sclose, H5Screate, H5Screate_simple, H5Sget_simple_extent_dims, H5Sget_simple_extent_ndims,
    H5Sselect_hyperslab, H5Sselect_none, H5S_SCALAR, H5S_SELECT_OR, H5S_SELECT_SET,
};
use hdf5_sys::h5t::{
    H5Tclose, H5Tcopy, H5Tget_class, H5Tget_size, H5Tis_variable_str, H5Tset_cset, H5Tset_size,
    H5Tset_strpad, H5T_CSET_UTF8, H5T_C_S1, H5T_NATIVE_DOUBLE, H5T_NATIVE_UINT32,
    H5T_NATIVE_UINT64, H5T_NATIVE_UINT8, H5T_STRING, H5T_STR_NULLPAD,
};

// Not declared by hdf5-sys: reports how the last transfer with this dxpl was performed
// (HDF5 may silently fall back to independent I/O, e.g. on a datatype conversion).
extern "C" {
    fn H5Pget_mpio_actual_io_mode(plist_id: hid_t, actual_io_mode: *mut c_int) -> herr_t;
}

/// How HDF5 actually performed a write (`H5D_mpio_actual_io_mode_t`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IoMode {
    /// Independent I/O: no collective transfer happened.
    NoCollective,
    /// Chunked dataset, every chunk written independently.
    ChunkIndependent,
    /// Chunked dataset, written collectively.
    ChunkCollective,
    /// Chunked dataset, some chunks collective, some independent.
    ChunkMixed,
    /// Contiguous dataset, written collectively.
    ContiguousCollective,
    /// A value this code does not know (newer HDF5).
    Other(i32),
}

impl IoMode {
    fn from_raw(raw: c_int) -> Self {
        match raw {
            0 => IoMode::NoCollective,
            1 => IoMode::ChunkIndependent,
            2 => IoMode::ChunkCollective,
            3 => IoMode::ChunkMixed,
            4 => IoMode::ContiguousCollective,
            other => IoMode::Other(other),
        }
    }

    /// Whether the whole transfer was collective.
    pub fn is_collective(self) -> bool {
        matches!(self, IoMode::ChunkCollective | IoMode::ContiguousCollective)
    }
}

/// Element types that can be written: their HDF5 native memory type.
pub trait Element: Copy + sealed::Sealed {
    /// The HDF5 native type id. Only valid after the library is initialised, i.e. inside
    /// `hdf5::sync::sync`.
    fn native_type() -> hid_t;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for f64 {}
    impl Sealed for u32 {}
    impl Sealed for u64 {}
    impl Sealed for u8 {}
}

impl Element for u8 {
    fn native_type() -> hid_t {
        *H5T_NATIVE_UINT8
    }
}

impl Element for f64 {
    fn native_type() -> hid_t {
        *H5T_NATIVE_DOUBLE
    }
}

impl Element for u32 {
    fn native_type() -> hid_t {
        *H5T_NATIVE_UINT32
    }
}

impl Element for u64 {
    fn native_type() -> hid_t {
        *H5T_NATIVE_UINT64
    }
}

/// Closes an HDF5 identifier when dropped, so every early return releases what it opened.
struct Owned {
    id: hid_t,
    close: unsafe extern "C" fn(hid_t) -> herr_t,
}

impl Owned {
    fn new(
        id: hid_t,
        close: unsafe extern "C" fn(hid_t) -> herr_t,
        what: &str,
    ) -> hdf5::Result<Self> {
        if id < 0 {
            Err(hdf5_error(what))
        } else {
            Ok(Owned { id, close })
        }
    }
}

impl Drop for Owned {
    fn drop(&mut self) {
        // SAFETY: `id` is a valid identifier of the kind `close` expects, closed once.
        unsafe {
            (self.close)(self.id);
        }
    }
}

/// The HDF5 error stack as an error (the hdf5 crate keeps stack printing silenced).
fn hdf5_error(what: &str) -> hdf5::Error {
    match hdf5::Error::query() {
        Ok(stack) | Err(stack) => hdf5::Error::from(format!("{what}: {stack}")),
    }
}

fn check(ret: herr_t, what: &str) -> hdf5::Result<()> {
    if ret < 0 {
        Err(hdf5_error(what))
    } else {
        Ok(())
    }
}

/// Writes this rank's contiguous block of rows into `dataset`, collectively.
///
/// `dataset` has `total` rows: shape `(total,)` when `columns == 1` (or `(total, 1)`), else
/// `(total, columns)`. `data` holds `rows × columns` values, row-major, which go to rows
/// `[offset, offset + rows)`. An empty `data` writes nothing but still takes part.
///
/// All ranks must call (collective).
///
/// Returns the I/O mode HDF5 reports for this rank's part of the transfer.
pub fn write_rows<T: Element>(
    dataset: &Dataset,
    data: &[T],
    columns: usize,
    offset: u64,
    total: u64,
) -> hdf5::Result<IoMode> {
    // A ragged `data` still forms one block, so that the validation below reports it.
    let rows = data.len().div_ceil(columns.max(1)) as u64;
    let block = [(offset, rows)];
    let blocks: &[(u64, u64)] = if data.is_empty() { &[] } else { &block };
    write_row_blocks(dataset, data, columns, blocks, total)
}

/// Writes this rank's rows into `dataset`, collectively, where the rows need not be
/// contiguous in the file: a rank owns grains scattered over the global order, and one
/// collective `H5Dwrite` per dataset (the file selection the union of the blocks, the
/// memory selection the packed rows) lets MPI-IO aggregate everything at once instead of
/// one write per block.
///
/// `blocks` lists `(offset, rows)` in ascending, non-overlapping order; `data` holds the
/// rows of all blocks packed in that order (`Σ rows × columns` values, row-major). The
/// dataset's shape is as for [`write_rows`]. No blocks (and empty `data`) writes nothing
/// but still takes part.
///
/// All ranks must call (collective).
///
/// Returns the I/O mode HDF5 reports for this rank's part of the transfer.
pub fn write_row_blocks<T: Element>(
    dataset: &Dataset,
    data: &[T],
    columns: usize,
    blocks: &[(u64, u64)],
    total: u64,
) -> hdf5::Result<IoMode> {
    hdf5::sync::sync(|| {
        // SAFETY: every id is checked and owned by an `Owned`; the buffer holds exactly the
        // number of elements selected in the memory space (Σ rows × columns, or none), and
        // the file selection selects the same number.
        unsafe {
            let ds = dataset.id();
            let file_space = Owned::new(H5Dget_space(ds), H5Sclose, "H5Dget_space")?;
            let problem = validate_blocks(file_space.id, data.len(), columns, blocks, total);
            // Invalid blocks still join the collective with an empty selection.
            let n = if problem.is_some() { 0 } else { data.len() };
            let n_mem = n as hsize_t;
            let mem_space = Owned::new(
                H5Screate_simple(1, &n_mem, std::ptr::null()),
                H5Sclose,
                "H5Screate_simple",
            )?;
            if n == 0 {
                check(H5Sselect_none(file_space.id), "H5Sselect_none")?;
                check(H5Sselect_none(mem_space.id), "H5Sselect_none")?;
            } else {
                let mut op = H5S_SELECT_SET;
                for &(offset, rows) in blocks.iter().filter(|b| b.1 > 0) {
                    // For a 1-D dataset HDF5 reads only the first entry of each array.
                    let start: [hsize_t; 2] = [offset, 0];
                    let count: [hsize_t; 2] = [rows, columns as hsize_t];
                    check(
                        H5Sselect_hyperslab(
                            file_space.id,
                            op,
                            start.as_ptr(),
                            std::ptr::null(),
                            count.as_ptr(),
                            std::ptr::null(),
                        ),
                        "H5Sselect_hyperslab",
                    )?;
                    op = H5S_SELECT_OR;
                }
            }
            let mode = write_collective(
                ds,
                T::native_type(),
                mem_space.id,
                file_space.id,
                data.as_ptr() as *const c_void,
            )?;
            match problem {
                Some(p) => Err(hdf5::Error::from(p)),
                None => Ok(mode),
            }
        }
    })
}

/// Checks row blocks and their data against the dataset's file space; `Some(reason)` if
/// they do not fit.
///
/// # Safety
/// `file_space` must be a valid dataspace id.
unsafe fn validate_blocks(
    file_space: hid_t,
    len: usize,
    columns: usize,
    blocks: &[(u64, u64)],
    total: u64,
) -> Option<String> {
    if columns == 0 {
        return Some("row block with 0 columns".to_string());
    }
    if !len.is_multiple_of(columns) {
        return Some(format!(
            "{len} values are not whole rows of {columns} columns"
        ));
    }
    let mut end = 0u64;
    let mut rows = 0u64;
    for (k, &(offset, n)) in blocks.iter().enumerate() {
        if k > 0 && offset < end {
            return Some(format!(
                "row block {k} starts at row {offset}, before the end {end} of the previous \
                 one (blocks must be ascending and must not overlap)"
            ));
        }
        end = match offset.checked_add(n) {
            Some(e) if e <= total => e,
            _ => {
                return Some(format!(
                    "rows [{offset}, {}) outside the {total} rows of the dataset",
                    offset.saturating_add(n)
                ))
            }
        };
        rows += n;
    }
    if rows != (len / columns) as u64 {
        return Some(format!(
            "{} rows of data for row blocks of {rows} rows",
            len / columns
        ));
    }
    let ndims = H5Sget_simple_extent_ndims(file_space);
    let mut dims: [hsize_t; 2] = [0; 2];
    if !(1..=2).contains(&ndims) {
        return Some(format!("dataset has rank {ndims}, expected 1 or 2"));
    }
    H5Sget_simple_extent_dims(file_space, dims.as_mut_ptr(), std::ptr::null_mut());
    let fits = if ndims == 1 {
        columns == 1 && dims[0] == total
    } else {
        dims[0] == total && dims[1] == columns as hsize_t
    };
    if fits {
        None
    } else {
        let shape = if ndims == 1 {
            format!("({})", dims[0])
        } else {
            format!("({}, {})", dims[0], dims[1])
        };
        Some(format!(
            "dataset shape {shape} does not match {total} rows of {columns} columns"
        ))
    }
}

/// `H5Dwrite` with a collective transfer property list; returns the actual I/O mode.
///
/// # Safety
/// Ids must be valid; `buf` must hold the elements selected in `mem_space`.
unsafe fn write_collective(
    ds: hid_t,
    mem_type: hid_t,
    mem_space: hid_t,
    file_space: hid_t,
    buf: *const c_void,
) -> hdf5::Result<IoMode> {
    let dxpl = Owned::new(
        H5Pcreate(*H5P_CLS_DATASET_XFER),
        H5Pclose,
        "H5Pcreate(dxpl)",
    )?;
    check(
        H5Pset_dxpl_mpio(dxpl.id, H5FD_mpio_xfer_t::H5FD_MPIO_COLLECTIVE),
        "H5Pset_dxpl_mpio",
    )?;
    check(
        H5Dwrite(ds, mem_type, mem_space, file_space, dxpl.id, buf),
        "H5Dwrite",
    )?;
    let mut raw: c_int = -1;
    check(
        H5Pget_mpio_actual_io_mode(dxpl.id, &mut raw),
        "H5Pget_mpio_actual_io_mode",
    )?;
    Ok(IoMode::from_raw(raw))
}

/// A 1-D `f64` dataset of `total` values: this rank's values go to `[offset, offset+len)`.
/// All ranks must call (collective).
pub fn write_1d_f64(ds: &Dataset, data: &[f64], offset: u64, total: u64) -> hdf5::Result<IoMode> {
    write_rows(ds, data, 1, offset, total)
}

/// A 1-D `u32` dataset (grain ids, owner ranks). All ranks must call (collective).
pub fn write_1d_u32(ds: &Dataset, data: &[u32], offset: u64, total: u64) -> hdf5::Result<IoMode> {
    write_rows(ds, data, 1, offset, total)
}

/// A 1-D `u64` dataset (global ids). All ranks must call (collective).
pub fn write_1d_u64(ds: &Dataset, data: &[u64], offset: u64, total: u64) -> hdf5::Result<IoMode> {
    write_rows(ds, data, 1, offset, total)
}

/// An `(total, k)` `f64` dataset (coordinates, vector and tensor fields): `data` holds
/// `rows × k` values row-major. All ranks must call (collective).
pub fn write_2d_f64(
    ds: &Dataset,
    data: &[f64],
    k: usize,
    offset: u64,
    total: u64,
) -> hdf5::Result<IoMode> {
    write_rows(ds, data, k, offset, total)
}

/// An `(total, k)` `u64` dataset (element connectivity). All ranks must call (collective).
pub fn write_2d_u64(
    ds: &Dataset,
    data: &[u64],
    k: usize,
    offset: u64,
    total: u64,
) -> hdf5::Result<IoMode> {
    write_rows(ds, data, k, offset, total)
}

/// Creates `parent/name` as a scalar fixed-length UTF-8 string dataset holding `text`
/// (null-padded, so it reads back byte-exact in h5py and h5dump) and writes it
/// collectively, the data coming from the rank with `is_writer` (the others select
/// nothing). Variable-length strings cannot be written by parallel HDF5 1.10, hence the
/// fixed length. All ranks must call (collective), with the same `text` length.
pub fn create_text_dataset(
    parent: &Group,
    name: &str,
    text: &str,
    is_writer: bool,
) -> hdf5::Result<Dataset> {
    let c_name = CString::new(name).map_err(|_| hdf5::Error::from("dataset name contains NUL"))?;
    hdf5::sync::sync(|| {
        // SAFETY: ids are checked and owned; the type is `text.len()` (≥ 1) bytes and the
        // buffer provides at least that many.
        unsafe {
            // A zero-size string type is invalid: store an empty text as one NUL byte.
            let padded;
            let bytes: &[u8] = if text.is_empty() {
                padded = [0u8; 1];
                &padded
            } else {
                text.as_bytes()
            };
            let dtype = Owned::new(H5Tcopy(*H5T_C_S1), H5Tclose, "H5Tcopy")?;
            check(H5Tset_size(dtype.id, bytes.len()), "H5Tset_size")?;
            check(H5Tset_cset(dtype.id, H5T_CSET_UTF8), "H5Tset_cset")?;
            check(H5Tset_strpad(dtype.id, H5T_STR_NULLPAD), "H5Tset_strpad")?;
            let file_space = Owned::new(H5Screate(H5S_SCALAR), H5Sclose, "H5Screate")?;
            let id = H5Dcreate2(
                parent.id(),
                c_name.as_ptr(),
                dtype.id,
                file_space.id,
                H5P_DEFAULT,
                H5P_DEFAULT,
                H5P_DEFAULT,
            );
            if id < 0 {
                return Err(hdf5_error(&format!("creating dataset {name}")));
            }
            // Takes ownership of `id` (closed when the Dataset drops).
            let dataset: Dataset = hdf5::from_id(id)?;
            let mem_space = Owned::new(H5Screate(H5S_SCALAR), H5Sclose, "H5Screate")?;
            if !is_writer {
                check(H5Sselect_none(file_space.id), "H5Sselect_none")?;
                check(H5Sselect_none(mem_space.id), "H5Sselect_none")?;
            }
            write_collective(
                id,
                dtype.id,
                mem_space.id,
                file_space.id,
                bytes.as_ptr() as *const c_void,
            )?;
            Ok(dataset)
        }
    })
}

/// Reads a scalar fixed-length string dataset written by [`create_text_dataset`] (any
/// file driver; not collective). Trailing NUL padding is removed.
pub fn read_text_dataset(dataset: &Dataset) -> hdf5::Result<String> {
    hdf5::sync::sync(|| {
        // SAFETY: the buffer is sized from the dataset's own (fixed-length) type.
        unsafe {
            let dtype = Owned::new(H5Dget_type(dataset.id()), H5Tclose, "H5Dget_type")?;
            if H5Tget_class(dtype.id) != H5T_STRING || H5Tis_variable_str(dtype.id) != 0 {
                return Err(hdf5::Error::from("not a fixed-length string dataset"));
            }
            let size = H5Tget_size(dtype.id);
            let mut buf = vec![0u8; size];
            check(
                H5Dread(
                    dataset.id(),
                    dtype.id,
                    hdf5_sys::h5s::H5S_ALL,
                    hdf5_sys::h5s::H5S_ALL,
                    H5P_DEFAULT,
                    buf.as_mut_ptr() as *mut c_void,
                ),
                "H5Dread",
            )?;
            while buf.last() == Some(&0) {
                buf.pop();
            }
            String::from_utf8(buf).map_err(|_| hdf5::Error::from("text is not UTF-8"))
        }
    })
}
