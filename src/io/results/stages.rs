//! `/stages`: what each finished stage of a staged run ended with (its span, why it ended,
//! the peak, failure and post-failure σ1/σ3 of a triaxial cell), so that the run's
//! headline figures are in the file and not only in its log.

use super::{put_str_attr, put_u64_attr, ResultsWriter};
use crate::error::MufeError;

/// One finished stage as `/stages/K_NAME` holds it (K its number, 1 = the first
/// `[[stages]]` entry): text and number attributes, the numbers in the SI units their
/// names say (docs/RESULTS.md).
#[derive(Debug, Clone, PartialEq)]
pub struct StageAttributes {
    pub number: u64,
    pub name: String,
    pub text: Vec<(&'static str, String)>,
    pub numbers: Vec<(&'static str, f64)>,
}

impl ResultsWriter<'_> {
    /// Replaces `/stages` with one group per finished stage (a continuing restart writes
    /// them all again, the earlier ones from its state). All ranks must call, with the
    /// same stages.
    pub fn write_stages(&mut self, stages: &[StageAttributes]) -> Result<(), MufeError> {
        let written = (|| -> hdf5::Result<()> {
            if self.file.link_exists("stages") {
                self.file.unlink("stages")?;
            }
            let group = self.file.create_group("stages")?;
            for s in stages {
                let g = group.create_group(&format!("{}_{}", s.number, s.name))?;
                put_u64_attr(&g, "number", s.number)?;
                put_str_attr(&g, "name", &s.name)?;
                for (key, value) in &s.text {
                    put_str_attr(&g, key, value)?;
                }
                for (key, value) in &s.numbers {
                    g.new_attr::<f64>().create(*key)?.write_scalar(value)?;
                }
            }
            Ok(())
        })();
        self.agree("writing /stages", written.map_err(|e| e.to_string()))
    }
}
