//! Surface-file grain shapes at scene load: field checks, file paths made relative to the
//! scene file, and each distinct shape read and checked once (defects are errors of the
//! surface file, before anything is meshed or MPI starts), its geometry kept for the
//! estimate, the speed bounds, the servo walls and `mufe check`'s shape descriptors.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use super::{Scene, ShapeSpec};
use crate::error::InputError;
use crate::mesh::import::{inspect, SurfaceGeometry};
use crate::mesh::MeshError;

pub(super) fn resolve(file: &str, scene: &mut Scene) -> Result<(), InputError> {
    let mut seen: BTreeMap<String, Arc<SurfaceGeometry>> = BTreeMap::new();
    for (i, g) in scene.grains.iter_mut().enumerate() {
        let ShapeSpec::Surface(spec) = &mut g.shape else {
            continue;
        };
        spec.validate().map_err(|e| match e {
            MeshError::InvalidSpec { field, message } => {
                InputError::new(file, format!("grains[{i}].shape.surface.{field}"), message)
            }
            other => other.for_grain(file, i),
        })?;
        spec.resolve_against(Path::new(file));
        let key = serde_json::to_string(&*spec).unwrap_or_default();
        let geometry = match seen.get(&key) {
            Some(g) => g.clone(),
            None => {
                let g = Arc::new(inspect(spec).map_err(|e| e.for_grain(file, i))?);
                seen.insert(key, g.clone());
                g
            }
        };
        spec.geometry = Some(geometry);
    }
    Ok(())
}
