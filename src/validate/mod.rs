//! Analytic validation cases (`mufe validate`): the contact laws of docs/THEORY.md must emerge
//! from the mesh. Each case is a scene in `jobs/validation/`, run at a list of meshing
//! ratios; the documented error metric compares the FE curve with the reference over the
//! whole loading range.

pub mod elliptic_hertz;
pub mod hertz;
pub mod hertz_ellipsoid;
pub mod mindlin_cyclic;
pub mod plastic_contact;
pub mod plastic_cube;
pub mod plastic_spheres;
pub mod record;
pub mod reference;
pub mod runner;
pub mod scenes;
pub mod thornton;
pub mod thornton_scene;
pub mod two_sphere;

use crate::error::InputError;
use runner::{Case, CaseOutcome};

/// Quick runs (`mufe validate --quick`, `tests/validation_quick.rs`) use one coarse
/// meshing ratio per case and this multiple of the full accuracy target.
pub const QUICK_TOLERANCE_FACTOR: f64 = 1.5;

/// All cases, in the order they run.
pub const CASE_NAMES: [&str; 10] = [
    "hertz",
    "hertz_ellipsoid",
    "mindlin",
    "mindlin_cyclic",
    "torsion",
    "rolling",
    "plastic_cube",
    "plastic_spheres",
    "thornton_walls",
    "thornton",
];

/// Resolves case names (empty: all) to case objects.
pub fn select_cases(names: &[String]) -> Result<Vec<Box<dyn Case>>, InputError> {
    let names: Vec<String> = if names.is_empty() {
        CASE_NAMES.iter().map(|s| s.to_string()).collect()
    } else {
        names.to_vec()
    };
    names
        .iter()
        .map(|n| -> Result<Box<dyn Case>, InputError> {
            match n.as_str() {
                "hertz" => Ok(Box::new(hertz::HertzCase)),
                "hertz_ellipsoid" => Ok(Box::new(hertz_ellipsoid::HertzEllipsoidCase)),
                "mindlin" => Ok(Box::new(two_sphere::TwoSphereCase {
                    kind: two_sphere::Kind::Mindlin,
                })),
                "mindlin_cyclic" => Ok(Box::new(two_sphere::TwoSphereCase {
                    kind: two_sphere::Kind::MindlinCyclic,
                })),
                "torsion" => Ok(Box::new(two_sphere::TwoSphereCase {
                    kind: two_sphere::Kind::Torsion,
                })),
                "rolling" => Ok(Box::new(two_sphere::TwoSphereCase {
                    kind: two_sphere::Kind::Rolling,
                })),
                "plastic_cube" => Ok(Box::new(plastic_cube::PlasticCubeCase)),
                "plastic_spheres" => Ok(Box::new(plastic_spheres::PlasticSpheresCase)),
                "thornton_walls" => Ok(Box::new(thornton::ThorntonCase { periodic: false })),
                "thornton" => Ok(Box::new(thornton::ThorntonCase { periodic: true })),
                other => Err(InputError::new(
                    "<command line>",
                    "CASE",
                    format!(
                        "unknown validation case '{other}' (known: {})",
                        CASE_NAMES.join(", ")
                    ),
                )),
            }
        })
        .collect()
}

/// Cases whose finest meshing ratio missed its target.
pub fn finest_failures(outcomes: &[CaseOutcome]) -> Vec<String> {
    let mut names: Vec<&str> = outcomes.iter().map(|o| o.case.as_str()).collect();
    names.dedup();
    names
        .into_iter()
        .filter_map(|n| {
            let finest = outcomes
                .iter()
                .filter(|o| o.case == n)
                .min_by(|a, b| a.mr.total_cmp(&b.mr))?;
            (!finest.pass).then(|| {
                format!(
                    "{} (MR {}, error {:.2}% > {:.1}%)",
                    n,
                    finest.mr,
                    100.0 * finest.error,
                    100.0 * finest.target
                )
            })
        })
        .collect()
}
