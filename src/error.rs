//! Errors that reach the user. Every user-facing failure is one line naming the file,
//! the field or item, and what is wrong; the CLI maps input errors to exit code 2.

use std::fmt;

/// An error caused by bad input (scene, mesh, checkpoint, command line): exit code 2.
#[derive(Debug, Clone, PartialEq)]
pub struct InputError {
    /// File the problem is in (scene path, mesh path, checkpoint), or `<command line>`.
    pub file: String,
    /// Dotted field path or item name (`grains[2].radius`, `element 17`).
    pub item: String,
    /// What is wrong, in words, with the offending value where it helps.
    pub message: String,
}

impl InputError {
    pub fn new(
        file: impl Into<String>,
        item: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            file: file.into(),
            item: item.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for InputError {
    /// Always one line: control characters (newlines included) are shown escaped, every
    /// run of non-blank characters longer than [`MAX_ECHO_CHARS`] (an echoed value) is cut
    /// with "…", and the file, item and message are capped so that a 10 MB value cannot
    /// flood the terminal.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = readable_path(&self.file, MAX_ITEM_CHARS);
        let message = readable(&self.message, MAX_MESSAGE_CHARS);
        if self.item.is_empty() {
            write!(f, "{file}: {message}")
        } else {
            let item = readable(&self.item, MAX_ITEM_CHARS);
            write!(f, "{file}: {item}: {message}")
        }
    }
}

/// Longest run of non-blank characters (a value, a path, a name) echoed in an error line.
pub const MAX_ECHO_CHARS: usize = 80;
/// Longest file or item part of an error line.
const MAX_ITEM_CHARS: usize = 200;
/// Longest message part of an error line.
const MAX_MESSAGE_CHARS: usize = 400;

/// A number as echoed in a message: plain for ordinary magnitudes (`0.3`, `2500`),
/// scientific otherwise (`1e-300`, not three hundred zeros).
pub fn num(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e7).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// `s` cut to at most `max` characters, ending with "…" when cut.
pub fn clip(s: &str, max: usize) -> String {
    if s.chars().count() <= max {
        return s.to_string();
    }
    let mut out: String = s.chars().take(max.saturating_sub(1)).collect();
    out.push('…');
    out
}

/// A value as echoed in an error message: control characters escaped (`\n`, `\u{1}`),
/// cut to [`MAX_ECHO_CHARS`].
pub fn echo(value: &str) -> String {
    clip(&escape_controls(value), MAX_ECHO_CHARS)
}

fn escape_controls(s: &str) -> String {
    if !s.chars().any(char::is_control) {
        return s.to_string();
    }
    s.chars()
        .map(|c| match c {
            '\n' => "\\n".to_string(),
            '\r' => "\\r".to_string(),
            '\t' => "\\t".to_string(),
            c if c.is_control() => c.escape_unicode().to_string(),
            c => c.to_string(),
        })
        .collect()
}

/// A file path on one line: controls escaped, and a path longer than `max_total` cut at
/// the front, since its end (the file name) is what names the file.
fn readable_path(s: &str, max_total: usize) -> String {
    let escaped = escape_controls(s);
    let n = escaped.chars().count();
    if n <= max_total {
        escaped
    } else {
        let tail: String = escaped.chars().skip(n - max_total).collect();
        format!("…{tail}")
    }
}

/// One readable line: controls escaped, long words (echoed values) cut, total capped.
fn readable(s: &str, max_total: usize) -> String {
    let mut out = String::new();
    let mut n_out = 0usize; // characters in `out`
    let mut n_word = 0usize; // characters of the current word seen so far
    for c in s.chars() {
        if n_out > max_total {
            break;
        }
        if c == ' ' {
            n_word = 0;
            out.push(' ');
            n_out += 1;
            continue;
        }
        n_word += 1;
        if n_word < MAX_ECHO_CHARS {
            let e = escape_controls(c.encode_utf8(&mut [0; 4]));
            n_out += e.chars().count();
            out.push_str(&e);
        } else if n_word == MAX_ECHO_CHARS {
            out.push('…');
            n_out += 1;
        }
    }
    clip(&out, max_total)
}

impl std::error::Error for InputError {}

/// Writes `line` and a newline to stderr in one `write` call.
///
/// `eprintln!` writes each piece of its format separately, so the lines of two MPI ranks
/// reporting at once come out interleaved mid-word when they share a pipe; a single write
/// of at most `PIPE_BUF` (4 KiB) bytes is atomic, and a reported line is far shorter.
pub fn report_line(line: impl std::fmt::Display) {
    use std::io::Write;
    let whole = format!("{line}\n");
    let _ = std::io::stderr().lock().write_all(whole.as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_path_keeps_its_file_name() {
        let path = format!("/{}/checkpoints/step_000000000150.h5", "deep/".repeat(60));
        let line = InputError::new(&path, "file", "damaged").to_string();
        assert!(
            line.contains("/checkpoints/step_000000000150.h5: file: damaged"),
            "{line}"
        );
        assert!(line.chars().count() < 260, "{line}");
    }

    #[test]
    fn long_values_are_cut_and_lines_stay_single() {
        let big = "x".repeat(10_000_000);
        let e = InputError::new("s.toml", "grains[0].name", format!("bad name '{big}'"));
        let line = e.to_string();
        assert!(line.chars().count() < 300, "{}", line.len());
        assert!(line.contains('…'));
        assert!(line.starts_with("s.toml: grains[0].name: bad name 'xxx"));
        let e = InputError::new("<command line>", "--set a=1\nb=2", "has a newline");
        assert_eq!(
            e.to_string(),
            "<command line>: --set a=1\\nb=2: has a newline"
        );
        assert!(!e.to_string().contains('\n'));
        let words = "ab ".repeat(1_000_000);
        let e = InputError::new("f", "i", words);
        assert!(e.to_string().chars().count() <= 420);
        assert_eq!(echo("short"), "short");
        assert_eq!(echo(&"y".repeat(100)).chars().count(), 80);
    }
}

/// Any failure of a run. `Input` → exit 2; everything else → exit 1.
#[derive(Debug)]
pub enum MufeError {
    Input(InputError),
    /// The simulation itself failed (blow-up, tunnelling detected, ...): names time, step, item.
    Run(String),
    /// I/O or HDF5 failure while writing results.
    Io(String),
    /// The run stopped on a signal after writing a checkpoint and its results (exit
    /// 128 + signal, the shell's convention for a signalled process).
    Stopped {
        signal: i32,
        message: String,
    },
}

impl fmt::Display for MufeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MufeError::Input(e) => write!(f, "{e}"),
            MufeError::Run(m) => write!(f, "{m}"),
            MufeError::Io(m) => write!(f, "{m}"),
            MufeError::Stopped { message, .. } => write!(f, "{message}"),
        }
    }
}

impl std::error::Error for MufeError {}

impl From<InputError> for MufeError {
    fn from(e: InputError) -> Self {
        MufeError::Input(e)
    }
}

impl MufeError {
    /// Process exit code for this error (docs/INPUT.md: bad input → 2).
    pub fn exit_code(&self) -> i32 {
        match self {
            MufeError::Input(_) => 2,
            MufeError::Stopped { signal, .. } => 128 + signal,
            _ => 1,
        }
    }
}

pub type Result<T, E = MufeError> = std::result::Result<T, E>;
