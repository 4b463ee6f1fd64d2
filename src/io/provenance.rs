//! Who produced a results file: version, ranks, threads, start time (UTC, ISO-8601), the
//! shell-quoted command line, the host and the element kernel, stored as attributes of `/provenance`.

use crate::domain::Domain;
use serde::{Deserialize, Serialize};
use std::time::{SystemTime, UNIX_EPOCH};

/// Who produced the file, stored as attributes of `/provenance`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Provenance {
    /// mufe version (`CARGO_PKG_VERSION`).
    pub version: String,
    /// Number of MPI ranks.
    pub ranks: usize,
    /// Threads per rank.
    pub threads: usize,
    /// Start of the run, UTC, ISO-8601 (`2024-05-01T12:00:00Z`).
    pub start_time: String,
    /// The command line, shell-quoted where needed.
    pub command_line: String,
    /// Host of rank 0.
    pub hostname: String,
    /// The compiled element loop the run uses (`portable`, `avx2` or `avx512`; they give
    /// bitwise identical forces).
    pub kernel: String,
}

impl Provenance {
    /// Provenance of this run, now. Local (not collective); the writer stores rank 0's.
    pub fn collect(domain: &Domain, threads: usize, kernel: &str) -> Self {
        Provenance {
            version: env!("CARGO_PKG_VERSION").to_string(),
            ranks: domain.size(),
            threads,
            start_time: iso8601_utc(SystemTime::now()),
            command_line: command_line(),
            hostname: domain.processor_name(),
            kernel: kernel.to_string(),
        }
    }
}

/// UTC time as ISO-8601 (`YYYY-MM-DDThh:mm:ssZ`), without a date crate.
pub fn iso8601_utc(t: SystemTime) -> String {
    let secs = match t.duration_since(UNIX_EPOCH) {
        Ok(d) => d.as_secs() as i64,
        Err(e) => -(e.duration().as_secs() as i64),
    };
    let days = secs.div_euclid(86_400);
    let sod = secs.rem_euclid(86_400);
    let (y, m, d) = civil_from_days(days);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        sod / 3600,
        sod % 3600 / 60,
        sod % 60
    )
}

/// Proleptic Gregorian date of a day count since 1970-01-01 (H. Hinnant's algorithm).
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// The process's command line, with arguments quoted for a POSIX shell where needed.
pub(crate) fn command_line() -> String {
    std::env::args_os()
        .map(|a| shell_quote(&a.to_string_lossy()))
        .collect::<Vec<_>>()
        .join(" ")
}

pub(crate) fn shell_quote(arg: &str) -> String {
    let plain = !arg.is_empty()
        && arg
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
    if plain {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}
