//! Row blocks: which rows of a dataset one rank writes.
//!
//! The file keeps every per-node, per-element and per-grain dataset in global grain order
//! (the rows of grain g start at the grain's global offset), whoever owns the grain. A rank
//! owns grains scattered over that order, so its rows are a list of `(offset, rows)` blocks,
//! ascending; its data are those rows packed in the same order. Before each collective
//! write the writer checks that the ranks' blocks tile the dataset exactly.

use crate::domain::Domain;

/// `(first row, rows)` of the rows of `grains` (ascending global ids) in a dataset laid out
/// by `offsets` (first row of each grain, the total at the end). Adjacent grains merge into
/// one block, so a rank owning a contiguous range of grains writes one hyperslab.
pub fn grain_row_blocks(
    grains: impl IntoIterator<Item = usize>,
    offsets: &[usize],
) -> Vec<(u64, u64)> {
    let mut blocks: Vec<(u64, u64)> = Vec::new();
    for g in grains {
        let (start, rows) = (offsets[g] as u64, (offsets[g + 1] - offsets[g]) as u64);
        match blocks.last_mut() {
            Some((o, n)) if *o + *n == start => *n += rows,
            _ if rows == 0 => {}
            _ => blocks.push((start, rows)),
        }
    }
    blocks
}

/// Global row of the `i`-th packed row of `blocks` (for error messages).
pub(crate) fn global_row(blocks: &[(u64, u64)], mut i: u64) -> u64 {
    for &(o, n) in blocks {
        if i < n {
            return o + i;
        }
        i -= n;
    }
    i
}

/// Checks one rank's blocks against its data before anything is created in the file:
/// ascending, non-overlapping, and holding `rows` rows in all.
pub(crate) fn check_local(blocks: &[(u64, u64)], rows: u64) -> Result<(), String> {
    let mut end = 0u64;
    for (k, &(o, n)) in blocks.iter().enumerate() {
        if k > 0 && o < end {
            return Err(format!(
                "row block {k} starts at row {o}, before the end {end} of the previous one \
                 (blocks must be ascending and must not overlap)"
            ));
        }
        end = o.saturating_add(n);
    }
    let in_blocks: u64 = blocks.iter().map(|b| b.1).sum();
    if in_blocks != rows {
        return Err(format!(
            "{rows} rows of data for row blocks of {in_blocks} rows"
        ));
    }
    Ok(())
}

/// Checks, for each row layout `(blocks, total)` of `layouts` (the same number, in the
/// same order, on every rank), that the ranks' blocks cover `[0, total)` exactly once and
/// that all ranks name the same total. Every rank's layouts are gathered to rank 0, which
/// judges, and the verdict is broadcast, so every rank returns the same `Err((index of
/// the first bad layout, message))` or `Ok`: three collectives for all layouts together
/// (each collective costs latency, and a frame has several layouts). All ranks must call.
pub(crate) fn check_tiling(
    domain: &Domain,
    layouts: &[(&[(u64, u64)], u64)],
) -> Result<(), (usize, String)> {
    // Per layout: total, block count, then the blocks. Counts as f64 are exact below 2⁵³.
    let values = layouts.iter().map(|(b, _)| 2 + 2 * b.len()).sum();
    let mut local = Vec::with_capacity(values);
    for &(blocks, total) in layouts {
        local.extend_from_slice(&[total as f64, blocks.len() as f64]);
        local.extend(blocks.iter().flat_map(|&(o, n)| [o as f64, n as f64]));
    }
    let lengths = domain.all_gather_u64(local.len() as u64);
    let mut verdict = match domain.gather_f64_to_root(&local) {
        Some(all) => judge(&all, &lengths, layouts.len()),
        None => Vec::new(),
    };
    domain.broadcast_bytes(&mut verdict);
    if verdict.len() < 4 {
        return Ok(());
    }
    let (index, message) = verdict.split_at(4);
    let index = u32::from_le_bytes(index.try_into().expect("4 bytes")) as usize;
    Err((index, String::from_utf8_lossy(message).into_owned()))
}

/// [`check_tiling`] for the fields of a frame, `layouts[i]` the `(blocks, total)` of field
/// i, with as little communication as the frames allow: fields share a few layouts (nodes,
/// elements, grains, contacts), which are checked once each, and a frame whose layouts
/// are those last verified (`verified`: every rank's hash of them, identical on all ranks)
/// costs one small all-gather; the layouts change only when grains migrate. An error names
/// the field (index into `layouts`). All ranks must call.
pub(crate) fn check_frame_tiling(
    domain: &Domain,
    layouts: &[(&[(u64, u64)], u64)],
    verified: &mut Vec<u64>,
) -> Result<(), (usize, String)> {
    // Distinct layouts on this rank, and which one each field has.
    let (mut distinct, mut first_field, mut which) = (Vec::new(), Vec::new(), Vec::new());
    for (i, layout) in layouts.iter().enumerate() {
        let k = distinct
            .iter()
            .position(|d| d == layout)
            .unwrap_or_else(|| {
                distinct.push(*layout);
                first_field.push(i);
                distinct.len() - 1
            });
        which.push(k as u32);
    }
    let which: Vec<u8> = which.iter().flat_map(|k| k.to_le_bytes()).collect();
    let mut key = which.clone();
    for &(blocks, total) in &distinct {
        key.extend_from_slice(&total.to_le_bytes());
        key.extend(
            blocks
                .iter()
                .flat_map(|&(o, n)| [o, n])
                .flat_map(u64::to_le_bytes),
        );
        key.push(0xff);
    }
    let hashes = domain.all_gather_u64(super::fnv1a(&key));
    if !verified.is_empty() && hashes == *verified {
        return Ok(());
    }
    // Which fields share a layout can differ between ranks (two fields whose blocks are
    // both empty here but not elsewhere): share only when every rank shares alike.
    let shares = domain.all_gather_u64(super::fnv1a(&which));
    let result = if shares.iter().all(|&s| s == shares[0]) {
        check_tiling(domain, &distinct).map_err(|(k, e)| (first_field[k], e))
    } else {
        check_tiling(domain, layouts)
    };
    *verified = if result.is_ok() { hashes } else { Vec::new() };
    result
}

/// Rank 0's verdict on the gathered layouts (`lengths[r]` values from rank r): empty if
/// all is well, else the index of the first bad layout (4 bytes, little-endian) and the
/// message.
fn judge(all: &[f64], lengths: &[u64], layouts: usize) -> Vec<u8> {
    let mut per_rank: Vec<&[f64]> = Vec::with_capacity(lengths.len());
    let mut rest = all;
    for &len in lengths {
        let (mine, tail) = rest.split_at((len as usize).min(rest.len()));
        per_rank.push(mine);
        rest = tail;
    }
    let verdict = |k: usize, problem: &str| {
        let mut v = (k as u32).to_le_bytes().to_vec();
        v.extend_from_slice(problem.as_bytes());
        v
    };
    for k in 0..layouts {
        let mut layout: Vec<(u64, Vec<(u64, u64)>)> = Vec::with_capacity(per_rank.len());
        for (r, values) in per_rank.iter_mut().enumerate() {
            // A rank that sent fewer layouts than rank 0 (a caller's bug) is an error, not
            // a panic on rank 0 that would leave the others waiting.
            let count = values.get(1).map_or(usize::MAX, |&c| c as usize);
            if count > (values.len().saturating_sub(2)) / 2 {
                return verdict(k, &format!("rank {r} describes fewer row layouts"));
            }
            let (head, tail) = values.split_at(2 + 2 * count);
            *values = tail;
            let blocks = head[2..]
                .chunks_exact(2)
                .map(|b| (b[0] as u64, b[1] as u64))
                .collect();
            layout.push((head[0] as u64, blocks));
        }
        if let Some(problem) = tiling_problem(&layout) {
            return verdict(k, &problem);
        }
    }
    Vec::new()
}

/// What is wrong with the ranks' `(total, blocks)`, rank by rank, if anything: totals that
/// differ, blocks that overlap, rows no rank writes.
pub(crate) fn tiling_problem(per_rank: &[(u64, Vec<(u64, u64)>)]) -> Option<String> {
    let total = per_rank.first().map_or(0, |r| r.0);
    if let Some(r) = per_rank.iter().position(|p| p.0 != total) {
        return Some(format!(
            "rank {r} says {} rows, rank 0 says {total}",
            per_rank[r].0
        ));
    }
    let mut all: Vec<(u64, u64, usize)> = per_rank
        .iter()
        .enumerate()
        .flat_map(|(r, (_, b))| b.iter().filter(|b| b.1 > 0).map(move |&(o, n)| (o, n, r)))
        .collect();
    all.sort_unstable();
    let (mut next, mut last_rank) = (0u64, None);
    for &(o, n, r) in &all {
        if o < next {
            let other = last_rank.map_or(String::new(), |q| format!(" of rank {q}"));
            return Some(format!(
                "rank {r} writes rows [{o}, {}), overlapping rows{other} up to {next} \
                 (blocks must not overlap)",
                o.saturating_add(n)
            ));
        }
        if o > next {
            return Some(format!("rows [{next}, {o}) are written by no rank"));
        }
        next = o.saturating_add(n);
        last_rank = Some(r);
    }
    if next != total {
        return Some(format!("the ranks write {next} rows of {total}"));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacent_grains_merge_into_one_block() {
        let offsets = [0, 4, 4, 9, 12, 20];
        assert_eq!(grain_row_blocks([0, 1, 2], &offsets), vec![(0, 9)]);
        assert_eq!(grain_row_blocks([0, 3], &offsets), vec![(0, 4), (9, 3)]);
        // an empty grain between two owned ones does not break the block
        assert_eq!(
            grain_row_blocks([0, 1, 2, 4], &offsets),
            vec![(0, 9), (12, 8)]
        );
        assert_eq!(grain_row_blocks([], &offsets), vec![]);
        assert_eq!(global_row(&[(0, 4), (9, 3)], 5), 10);
    }

    #[test]
    fn gathered_layouts_are_judged_per_layout() {
        // two ranks, two layouts each: (total, count, blocks...) per layout
        let r0 = [4.0, 1.0, 0.0, 2.0, 3.0, 1.0, 0.0, 2.0];
        let r1 = [4.0, 1.0, 2.0, 2.0, 3.0, 1.0, 2.0, 1.0];
        let all: Vec<f64> = r0.iter().chain(&r1).copied().collect();
        assert!(judge(&all, &[8, 8], 2).is_empty());
        let bad = [4.0, 1.0, 2.0, 2.0, 3.0, 1.0, 1.0, 2.0];
        let all: Vec<f64> = r0.iter().chain(&bad).copied().collect();
        let v = judge(&all, &[8, 8], 2);
        assert_eq!(
            u32::from_le_bytes(v[..4].try_into().unwrap()),
            1,
            "second layout"
        );
        // a rank with fewer layouts is reported, not a panic
        let all: Vec<f64> = r0.iter().chain(&r1[..4]).copied().collect();
        let v = judge(&all, &[8, 4], 2);
        assert!(String::from_utf8_lossy(&v[4..]).contains("rank 1 describes fewer"));
    }

    #[test]
    fn frame_layouts_are_checked_once_until_they_change() {
        crate::domain::with_test_domain(|d| {
            let (nodes, grains) = ([(0u64, 5u64)], [(0u64, 2u64)]);
            let layouts = [(&nodes[..], 5), (&nodes[..], 5), (&grains[..], 2)];
            let mut verified = Vec::new();
            assert_eq!(check_frame_tiling(d, &layouts, &mut verified), Ok(()));
            assert_eq!(verified.len(), 1);
            assert_eq!(check_frame_tiling(d, &layouts, &mut verified), Ok(()));
            let gap = [(0u64, 1u64)];
            let bad = [(&nodes[..], 5), (&gap[..], 2)];
            let (field, message) = check_frame_tiling(d, &bad, &mut verified).unwrap_err();
            assert_eq!(field, 1);
            assert!(message.contains("1 rows of 2"), "{message}");
            assert!(verified.is_empty());
        });
    }

    #[test]
    fn tiling_is_judged_over_all_ranks() {
        let ok = [(10, vec![(0, 2), (6, 4)]), (10, vec![(2, 4)])];
        assert_eq!(tiling_problem(&ok), None);
        let empty_rank = [(3, vec![(0, 3)]), (3, vec![])];
        assert_eq!(tiling_problem(&empty_rank), None);
        let overlap = [(10, vec![(0, 5)]), (10, vec![(4, 6)])];
        let m = tiling_problem(&overlap).unwrap();
        assert!(m.contains("rank 1") && m.contains("overlap"), "{m}");
        let gap = [(10, vec![(0, 4)]), (10, vec![(5, 5)])];
        assert!(tiling_problem(&gap).unwrap().contains("[4, 5)"));
        let short = [(10, vec![(0, 4)]), (10, vec![(4, 5)])];
        assert!(tiling_problem(&short).unwrap().contains("9 rows of 10"));
        let totals = [(10, vec![(0, 4)]), (11, vec![(4, 6)])];
        assert!(tiling_problem(&totals).unwrap().contains("rank 1 says 11"));
    }
}
