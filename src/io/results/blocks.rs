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

/// Checks that the ranks' blocks cover `[0, total)` exactly once and that all ranks name
/// the same total: every rank's blocks and total are gathered to rank 0, which judges, and
/// the verdict is broadcast, so every rank returns the same `Err(message)` or `Ok`.
/// All ranks must call.
pub(crate) fn check_tiling(
    domain: &Domain,
    blocks: &[(u64, u64)],
    total: u64,
) -> Result<(), String> {
    // Counts as f64 are exact below 2⁵³ rows.
    let mut local = Vec::with_capacity(1 + 2 * blocks.len());
    local.push(total as f64);
    local.extend(blocks.iter().flat_map(|&(o, n)| [o as f64, n as f64]));
    let lengths = domain.all_gather_u64(local.len() as u64);
    let mut verdict = match domain.gather_f64_to_root(&local) {
        Some(all) => {
            let mut per_rank = Vec::with_capacity(lengths.len());
            let mut rest = &all[..];
            for &len in &lengths {
                let (mine, tail) = rest.split_at(len as usize);
                rest = tail;
                let blocks = mine[1..]
                    .chunks_exact(2)
                    .map(|b| (b[0] as u64, b[1] as u64))
                    .collect();
                per_rank.push((mine[0] as u64, blocks));
            }
            tiling_problem(&per_rank).unwrap_or_default().into_bytes()
        }
        None => Vec::new(),
    };
    domain.broadcast_bytes(&mut verdict);
    if verdict.is_empty() {
        Ok(())
    } else {
        Err(String::from_utf8_lossy(&verdict).into_owned())
    }
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
