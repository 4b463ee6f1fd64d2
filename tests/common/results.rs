//! Reading `results.h5` back in tests.
//!
//! Use from a test file with `#[path = "common/results.rs"] mod results;`.
#![allow(dead_code)]

use std::path::Path;

/// All `/history` series of a results file, by name (sorted).
pub fn history(path: &Path) -> Vec<(String, Vec<f64>)> {
    let f = hdf5::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let g = f.group("history").unwrap();
    let mut names = g.member_names().unwrap();
    names.sort();
    names
        .into_iter()
        .map(|n| (n.clone(), g.dataset(&n).unwrap().read_raw::<f64>().unwrap()))
        .collect()
}

/// The series `name` of a [`history`] (panics naming it when missing).
pub fn column<'a>(h: &'a [(String, Vec<f64>)], name: &str) -> &'a [f64] {
    &h.iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("/history/{name} missing"))
        .1
}
