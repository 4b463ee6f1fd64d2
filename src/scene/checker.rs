//! The checks every semantic validation is made of: each failure names the file and the
//! dotted field (`Checker`), and the servo settings shared by walls and stages.

use super::{History3, Scene, ServoSpec, WallSpec};
use crate::error::{echo, num, InputError};

pub(super) struct Checker<'a> {
    pub(super) file: &'a str,
}

impl Checker<'_> {
    pub(super) fn err(&self, field: impl Into<String>, msg: impl Into<String>) -> InputError {
        InputError::new(self.file, field, msg)
    }

    pub(super) fn finite(&self, field: &str, v: f64) -> Result<(), InputError> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(self.err(field, format!("must be a finite number, got {}", num(v))))
        }
    }

    pub(super) fn positive(&self, field: &str, v: f64) -> Result<(), InputError> {
        self.finite(field, v)?;
        if v > 0.0 {
            Ok(())
        } else {
            Err(self.err(field, format!("must be > 0, got {}", num(v))))
        }
    }

    pub(super) fn non_negative(&self, field: &str, v: f64) -> Result<(), InputError> {
        self.finite(field, v)?;
        if v >= 0.0 {
            Ok(())
        } else {
            Err(self.err(field, format!("must be ≥ 0, got {}", num(v))))
        }
    }

    pub(super) fn vec3(&self, field: &str, v: &[f64; 3]) -> Result<(), InputError> {
        for (i, c) in v.iter().enumerate() {
            self.finite(&format!("{field}[{i}]"), *c)?;
        }
        Ok(())
    }

    pub(super) fn nonzero_vec3(&self, field: &str, v: &[f64; 3]) -> Result<(), InputError> {
        self.vec3(field, v)?;
        if v.iter().map(|c| c * c).sum::<f64>() == 0.0 {
            return Err(self.err(field, "must not be the zero vector"));
        }
        Ok(())
    }

    /// Names used in history column names: letters, digits and `_` only.
    pub(super) fn identifier(&self, field: &str, name: &str) -> Result<(), InputError> {
        if name.is_empty()
            || !name
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '_')
        {
            return Err(self.err(field, "must be a non-empty identifier (letters, digits, _)"));
        }
        Ok(())
    }

    /// A translation given by at most one of a velocity and a displacement history.
    /// `prefix` ends with '.' (e.g. `walls[0].`).
    pub(super) fn translation(
        &self,
        prefix: &str,
        velocity: &Option<History3>,
        displacement: &Option<History3>,
    ) -> Result<(), InputError> {
        if velocity.is_some() && displacement.is_some() {
            return Err(self.err(
                format!("{prefix}velocity"),
                "give either velocity or displacement, not both",
            ));
        }
        if let Some(h) = velocity {
            self.history(&format!("{prefix}velocity"), h)?;
        }
        if let Some(h) = displacement {
            self.history(&format!("{prefix}displacement"), h)?;
        }
        Ok(())
    }

    pub(super) fn history(&self, field: &str, h: &History3) -> Result<(), InputError> {
        if h.times.is_empty() {
            return Err(self.err(format!("{field}.times"), "needs at least one time"));
        }
        if h.times.len() != h.values.len() {
            return Err(self.err(
                field,
                format!("{} times but {} values", h.times.len(), h.values.len()),
            ));
        }
        for (i, t) in h.times.iter().enumerate() {
            self.non_negative(&format!("{field}.times[{i}]"), *t)?;
            if i > 0 && *t <= h.times[i - 1] {
                return Err(self.err(
                    format!("{field}.times[{i}]"),
                    format!(
                        "times must increase strictly, got {} after {}",
                        num(*t),
                        num(h.times[i - 1])
                    ),
                ));
            }
        }
        for (i, v) in h.values.iter().enumerate() {
            self.vec3(&format!("{field}.values[{i}]"), v)?;
        }
        Ok(())
    }
}

/// Checks a servo spec of wall `w`; `prefix` is its dotted field (`walls[1].servo`).
pub(super) fn validate_servo(
    c: &Checker,
    scene: &Scene,
    prefix: &str,
    w: &WallSpec,
    servo: &ServoSpec,
) -> Result<(), InputError> {
    let f = |x: &str| format!("{prefix}{x}");
    c.positive(&f(".stress"), servo.stress)?;
    match (&servo.area, &servo.area_of) {
        (Some(_), Some(_)) => {
            return Err(c.err(f(".area"), "give either area or area_of, not both"))
        }
        (None, None) => return Err(c.err(f(""), "needs area (m²) or area_of (a packing name)")),
        (Some(a), None) => c.positive(&f(".area"), *a)?,
        (None, Some(name)) => {
            if !scene.packings.iter().any(|p| &p.name == name) {
                return Err(c.err(f(".area_of"), format!("no packing named '{}'", echo(name))));
            }
            if super::normal_axis(w.normal).is_none() {
                return Err(c.err(
                    f(".area_of"),
                    "needs the wall normal along a coordinate axis (the area is the packing's span across it)",
                ));
            }
        }
    }
    if servo.time_constant.is_some() && servo.periods.is_some() {
        return Err(c.err(
            f(".periods"),
            "give either time_constant (s) or periods (of the specimen's lowest mode), not both",
        ));
    }
    for (field, v) in [
        (".time_constant", servo.time_constant),
        (".periods", servo.periods),
        (".max_speed", servo.max_speed),
        (".stiffness", servo.stiffness),
    ] {
        if let Some(v) = v {
            c.positive(&f(field), v)?;
        }
    }
    Ok(())
}
