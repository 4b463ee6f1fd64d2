//! Plain-text partition files, so a partition can be computed once, inspected,
//! edited or produced by another tool, and read back by every rank.
//!
//! Format: `#` starts a comment line, blank lines are ignored, every other line
//! is `grain_id part` (two unsigned integers separated by white space). Each
//! grain `0..n_grains` must appear exactly once, in any order. Example:
//!
//! ```text
//! # mufe grain partition: 4 grains, 2 parts
//! # grain_id part
//! 0 0
//! 1 0
//! 2 1
//! 3 1
//! ```

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;

use crate::error::PartitionError;

/// Writes `part[grain]` to `path` (created or truncated) with a header comment.
///
/// # Errors
/// [`PartitionError::Io`] naming the file if it cannot be created or written.
pub fn write_partition(path: impl AsRef<Path>, part: &[u32]) -> Result<(), PartitionError> {
    let path = path.as_ref();
    let io_error = |e: std::io::Error| PartitionError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let parts = part.iter().max().map_or(0, |&p| u64::from(p) + 1);
    let mut out = BufWriter::new(File::create(path).map_err(io_error)?);
    writeln!(
        out,
        "# mufe grain partition: {} grains, {parts} parts",
        part.len()
    )
    .map_err(io_error)?;
    writeln!(out, "# grain_id part").map_err(io_error)?;
    for (grain, p) in part.iter().enumerate() {
        writeln!(out, "{grain} {p}").map_err(io_error)?;
    }
    out.flush().map_err(io_error)
}

/// Reads a partition of `n_grains` grains from `path`.
///
/// # Errors
/// [`PartitionError::Io`] if the file cannot be opened;
/// [`PartitionError::Parse`] with the file and 1-based line number for a line
/// that is not two unsigned integers, a grain id ≥ `n_grains` or a grain listed
/// twice; and (without a line) if some grain is missing.
pub fn read_partition(path: impl AsRef<Path>, n_grains: usize) -> Result<Vec<u32>, PartitionError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|e| PartitionError::Io {
        path: path.to_path_buf(),
        message: format!("cannot open partition file: {e}"),
    })?;
    let parse_error = |line: Option<usize>, message: String| PartitionError::Parse {
        path: path.to_path_buf(),
        line,
        message,
    };

    let mut part: Vec<Option<u32>> = vec![None; n_grains];
    for (index, line) in BufReader::new(file).lines().enumerate() {
        let line_number = index + 1;
        let line = line.map_err(|e| parse_error(Some(line_number), e.to_string()))?;
        let content = line.trim();
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = content.split_whitespace().collect();
        let [grain_field, part_field] = fields.as_slice() else {
            return Err(parse_error(
                Some(line_number),
                format!(
                    "expected `grain_id part`, found {} field(s): `{content}`",
                    fields.len()
                ),
            ));
        };
        let grain: usize = grain_field.parse().map_err(|_| {
            parse_error(
                Some(line_number),
                format!("grain id `{grain_field}` is not an unsigned integer"),
            )
        })?;
        let part_id: u32 = part_field.parse().map_err(|_| {
            parse_error(
                Some(line_number),
                format!("part `{part_field}` is not an unsigned 32-bit integer"),
            )
        })?;
        let Some(slot) = part.get_mut(grain) else {
            return Err(parse_error(
                Some(line_number),
                format!("grain id {grain} out of range: there are {n_grains} grains (ids 0..{n_grains})"),
            ));
        };
        if let Some(previous) = *slot {
            return Err(parse_error(
                Some(line_number),
                format!("grain {grain} listed twice (already assigned to part {previous})"),
            ));
        }
        *slot = Some(part_id);
    }

    let missing: Vec<usize> = (0..n_grains).filter(|&g| part[g].is_none()).collect();
    if let Some(&first) = missing.first() {
        let others = match missing.len() - 1 {
            0 => String::new(),
            n => format!(" and {n} other grain(s)"),
        };
        return Err(parse_error(
            None,
            format!("grain {first}{others} missing; expected one line for each of the {n_grains} grains"),
        ));
    }
    Ok(part.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// A fresh file path in the system temp directory, unique per test.
    fn temp_path(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!(
            "mufe-partition-test-{}-{name}.txt",
            std::process::id()
        ))
    }

    fn read_text(name: &str, text: &str, n_grains: usize) -> Result<Vec<u32>, PartitionError> {
        let path = temp_path(name);
        std::fs::write(&path, text).unwrap();
        let result = read_partition(&path, n_grains);
        std::fs::remove_file(&path).ok();
        result
    }

    #[test]
    fn round_trip() {
        let part: Vec<u32> = (0..1000u32).map(|i| (i * 7) % 13).collect();
        let path = temp_path("round-trip");
        write_partition(&path, &part).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("# mufe grain partition: 1000 grains, 13 parts\n"));
        assert_eq!(read_partition(&path, part.len()).unwrap(), part);
        std::fs::remove_file(&path).ok();

        let empty = temp_path("round-trip-empty");
        write_partition(&empty, &[]).unwrap();
        assert_eq!(read_partition(&empty, 0).unwrap(), Vec::<u32>::new());
        std::fs::remove_file(&empty).ok();
    }

    #[test]
    fn accepts_any_order_comments_and_blank_lines() {
        let text = "# header\n\n2 5\n  0 1  \n# middle\n1\t3\n";
        assert_eq!(read_text("order", text, 3).unwrap(), vec![1, 3, 5]);
    }

    #[test]
    fn bad_files_name_the_file_and_line() {
        let cases = [
            ("fields", "0 0\n1 0 7\n", 2, Some(2), "field"),
            ("grain-nan", "0 0\nx 1\n", 2, Some(2), "grain id `x`"),
            ("part-nan", "0 -1\n1 0\n", 2, Some(1), "part `-1`"),
            ("range", "0 0\n1 0\n2 0\n", 2, Some(3), "out of range"),
            ("twice", "0 0\n# c\n0 1\n", 2, Some(3), "listed twice"),
            (
                "missing",
                "0 0\n",
                3,
                None,
                "grain 1 and 1 other grain(s) missing",
            ),
        ];
        for (name, text, n_grains, expected_line, expected_text) in cases {
            let err = read_text(name, text, n_grains).unwrap_err();
            let PartitionError::Parse { ref path, line, .. } = err else {
                panic!("{name}: expected a parse error, got {err:?}");
            };
            assert_eq!(line, expected_line, "{name}: {err}");
            let message = err.to_string();
            assert!(message.contains(expected_text), "{name}: {message}");
            assert!(
                message.starts_with(&path.display().to_string()),
                "{name}: {message}"
            );
            if let Some(line) = expected_line {
                assert!(message.contains(&format!(":{line}: ")), "{name}: {message}");
            }
            assert_eq!(message.lines().count(), 1, "{name}: one-line message");
        }
    }

    #[test]
    fn missing_file_and_unwritable_path_are_io_errors() {
        let path = temp_path("does-not-exist");
        let err = read_partition(&path, 1).unwrap_err();
        assert!(matches!(err, PartitionError::Io { .. }), "{err:?}");
        assert!(err.to_string().contains("does-not-exist"), "{err}");

        let dir_path = std::env::temp_dir()
            .join("mufe-no-such-dir-for-partition")
            .join("p.txt");
        let err = write_partition(&dir_path, &[0]).unwrap_err();
        assert!(matches!(err, PartitionError::Io { .. }), "{err:?}");
    }
}
