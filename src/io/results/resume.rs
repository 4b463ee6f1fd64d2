//! Reopening `results.h5` to continue a run from a checkpoint: the history rows and
//! frames written after the checkpoint's step are dropped (the restarted run writes them
//! again, identically), so the file reads as if the run had never stopped.

use super::{agree, io_error, History, HistoryColumn, ResultsWriter};
use crate::domain::Domain;
use crate::error::MufeError;
use hdf5::File;
use std::path::Path;

/// The history datasets, their values and how many rows to keep.
type HistoryRead = (Vec<hdf5::Dataset>, Vec<Vec<f64>>, usize);

/// What a reopened file already holds.
pub struct Resumed<'d> {
    pub writer: ResultsWriter<'d>,
    /// The history rows kept (row-major, one value per column).
    pub rows: Vec<Vec<f64>>,
    /// (index, time) of the frames kept.
    pub frames: Vec<(usize, f64)>,
}

impl<'d> ResultsWriter<'d> {
    /// Opens `path` for appending after a checkpoint at step `step`, time `time`: keeps
    /// the history rows of steps before `step` (a row describes the step that produced it)
    /// and the frames at times ≤ `time`; the file's history columns must be `columns`.
    ///
    /// All ranks must call.
    pub fn resume(
        domain: &'d Domain,
        path: &Path,
        columns: &[HistoryColumn],
        step: u64,
        time: f64,
    ) -> Result<Resumed<'d>, MufeError> {
        let opened = File::with_options()
            .with_fapl(|p| p.mpio(domain.raw_comm(), None))
            .open_rw(path)
            .map_err(|e| e.to_string());
        agree(
            domain,
            path,
            "reopening results file",
            opened.as_ref().map(|_| ()).map_err(Clone::clone),
        )?;
        let file = opened.map_err(|e| io_error(path, "reopening results file", e))?;
        let version = (file.attr("format_version")).and_then(|a| a.read_scalar::<u64>());
        if version.as_ref().ok() != Some(&super::RESULTS_FORMAT) {
            let found = version.map_or("no format_version".to_string(), |v| format!("format {v}"));
            return Err(crate::error::InputError::new(
                path.display().to_string(),
                "format_version",
                format!(
                    "{found}; this mufe continues results files of format {} only: restart into a new --out with --branch",
                    super::RESULTS_FORMAT
                ),
            )
            .into());
        }

        let read = (|| -> Result<HistoryRead, String> {
            let group = file
                .group("history")
                .map_err(|e| format!("/history: {e}"))?;
            let mut datasets = Vec::with_capacity(columns.len());
            let mut values = Vec::with_capacity(columns.len());
            for c in columns {
                let ds = group.dataset(&c.name).map_err(|_| {
                    format!(
                        "no /history/{}: the file was written by another scene or version",
                        c.name
                    )
                })?;
                values.push(
                    ds.read_raw::<f64>()
                        .map_err(|e| format!("/history/{}: {e}", c.name))?,
                );
                datasets.push(ds);
            }
            let steps = columns
                .iter()
                .position(|c| c.name == "step")
                .map(|k| values[k].clone())
                .unwrap_or_default();
            let keep = steps.iter().take_while(|&&s| s < step as f64).count();
            // every column reached the rows before the checkpoint (they were flushed
            // before it was written); one that did not is a damaged file, not a panic
            if let Some((c, v)) = columns.iter().zip(&values).find(|(_, v)| v.len() < keep) {
                return Err(format!(
                    "/history/{} has {} rows where /history/step has {keep} before the checkpoint: the file is damaged",
                    c.name,
                    v.len()
                ));
            }
            Ok((datasets, values, keep))
        })();
        agree(
            domain,
            path,
            "reading /history",
            read.as_ref().map(|_| ()).map_err(Clone::clone),
        )?;
        let (datasets, values, keep) = read.map_err(|e| io_error(path, "reading /history", e))?;

        let trimmed = (|| -> hdf5::Result<Vec<(usize, f64)>> {
            for ds in &datasets {
                ds.resize(keep)?;
            }
            let mut frames = Vec::new();
            if let Ok(group) = file.group("frames") {
                let mut names = group.member_names()?;
                names.sort();
                for name in names {
                    let t: f64 = group.group(&name)?.attr("time")?.read_scalar()?;
                    if t <= time {
                        frames.push((name.parse().unwrap_or(frames.len()), t));
                    } else {
                        group.unlink(&name)?;
                    }
                }
            }
            Ok(frames)
        })();
        agree(
            domain,
            path,
            "dropping rows and frames after the checkpoint",
            trimmed.as_ref().map(|_| ()).map_err(|e| e.to_string()),
        )?;
        let frames = trimmed.map_err(|e| io_error(path, "trimming", e))?;

        let rows = (0..keep)
            .map(|i| values.iter().map(|col| col[i]).collect())
            .collect();
        let writer = ResultsWriter {
            domain,
            path: path.to_path_buf(),
            history: Some(History {
                columns: columns.to_vec(),
                datasets,
                pending: Vec::new(),
                rows_written: keep as u64,
            }),
            io: Default::default(),
            verified_layouts: Vec::new(),
            file,
        };
        writer.flush_file()?;
        Ok(Resumed {
            writer,
            rows,
            frames,
        })
    }
}

impl ResultsWriter<'_> {
    /// A text attribute of `/provenance` (`None` if the file has none: older files).
    pub fn provenance_text(&self, name: &str) -> Option<String> {
        let value = self.file.group("provenance").ok()?.attr(name).ok()?;
        let text = value.read_scalar::<hdf5::types::VarLenUnicode>().ok()?;
        Some(text.as_str().to_string())
    }

    /// Records a restart or branch in `/provenance` as attribute `KIND_N` (N counting the
    /// file's earlier ones of that kind), rank 0's `note` on all ranks. All ranks must
    /// call.
    pub fn note_provenance(&mut self, kind: &str, note: &str) -> Result<(), MufeError> {
        let mut bytes = note.as_bytes().to_vec();
        self.domain.broadcast_bytes(&mut bytes);
        let note = String::from_utf8_lossy(&bytes).into_owned();
        let written = (|| -> hdf5::Result<()> {
            let group = self.file.group("provenance")?;
            let earlier = group
                .attr_names()?
                .iter()
                .filter(|n| n.starts_with(&format!("{kind}_")))
                .count();
            super::put_str_attr(&group, &format!("{kind}_{earlier}"), &note)
        })();
        agree(
            self.domain,
            &self.path,
            "recording the restart in /provenance",
            written.map_err(|e| e.to_string()),
        )?;
        self.flush_file()
    }
}
