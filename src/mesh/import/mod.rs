//! Grains of any shape from surface files (STL, OBJ, Gmsh MSH 4.1): read, scale to metres,
//! check (and optionally repair), centre, remesh to the seeding and fill with tets by
//! TetGen; or, for an MSH volume mesh, use its tets as they are. See docs/SHAPES.md.
//!
//! Pipeline of [`mesh_surface`]: [`prepare`] (read → units × scale → repair → checks →
//! origin) → on-disk cache lookup (`cache`) → [`remesh`] onto the file's surface to the
//! size field (or, with `remesh = false`, `refine::subdivide_to` edges ≤ the size) → BCC
//! interior points ([`zones::interior_points`]) → TetGen with the sphere mesher's
//! radius–edge bound and no volume bound → interior smoothing → rotation. Defects are
//! input errors naming the surface file and the first bad facet.

pub mod cache;
pub mod checks;
mod descriptors;
pub mod formats;
pub mod intersect;
mod refine;
pub mod remesh;
pub mod zones;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};

pub use descriptors::ShapeDescriptors;
pub use formats::{Format, Imported};

use super::tetgen::tetrahedralize;
use super::{MeshError, TetMesh};
use crate::error::{num, InputError};
use crate::math::{norm, sub};

/// Bumped whenever a change to this pipeline changes the meshes (invalidates the cache).
const MESHER_VERSION: u32 = 6;

/// Largest surface after subdivision (facets): ~100 M tets.
const MAX_FACETS: usize = 4_000_000;

/// A closed triangulated surface: facets counter-clockwise seen from outside once checked.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Surface {
    pub points: Vec<[f64; 3]>,
    pub facets: Vec<[u32; 3]>,
}

/// Where the grain's origin (its `centre` in the scene) is in the file's geometry.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SurfaceOrigin {
    /// The volume centroid of the shape (default).
    #[default]
    Centroid,
    /// The file's own origin (after units and scale).
    File,
}

/// A grain shape read from a surface file.
///
/// ```toml
/// shape = { surface = { file = "grain.stl", units = "mm", seeding = 1.0e-4, scale = 1.0, rotation = [0.0, 0.0, 1.5708], repair = false } }
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceSpec {
    /// `.stl` (binary or ASCII), `.obj` or `.msh` (Gmsh 4.1 ASCII); relative paths are
    /// relative to the scene file (resolved when the scene is loaded).
    pub file: String,
    /// Length unit of the file's coordinates: `m`, `cm`, `mm`, `um` (or `µm`).
    pub units: String,
    /// Target element edge (m, after units and scale). Ignored for MSH volume meshes.
    pub seeding: f64,
    /// Factor applied after the unit conversion (–), default 1.
    #[serde(default = "one")]
    pub scale: f64,
    /// Rotation of the shape about its origin, as an axis-angle vector (rad): the axis is
    /// the direction, the angle (right-handed) the length. Applied before the grain is
    /// moved to its `centre`. Default none.
    #[serde(default)]
    pub rotation: [f64; 3],
    /// Repair what is safely repairable (near-duplicate vertices, degenerate and repeated
    /// facets, flipped facets) and say what changed on stderr. Default false.
    #[serde(default)]
    pub repair: bool,
    /// `centroid` (default) or `file`: which point of the shape is placed at `centre`.
    #[serde(default)]
    pub origin: SurfaceOrigin,
    /// Zones of finer facets and elements around points of the shape (grain frame, before
    /// rotation); see [`zones`]. Default none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub refine: Vec<zones::SurfaceRefinement>,
    /// Remesh the surface to the seeding (and the zones and curvature sizing) on the file's
    /// own geometry ([`remesh`]); `false` keeps the file's facets, only splitting those
    /// longer than the size. Default true.
    #[serde(default = "yes")]
    pub remesh: bool,
    /// Finer facets where the surface is curved (needs `remesh`); see
    /// [`remesh::CurvatureSizing`]. Default none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub curvature: Option<remesh::CurvatureSizing>,
    /// Checked geometry, filled when the scene is loaded (not input).
    #[serde(skip)]
    pub geometry: Option<Arc<SurfaceGeometry>>,
}

impl Surface {
    /// Area-weighted vertex normals of a closed surface (unnormalised: the sum of the
    /// doubled area vectors of the facets around each vertex).
    pub fn vertex_normals(&self) -> Vec<[f64; 3]> {
        let mut normals = vec![[0.0; 3]; self.points.len()];
        for f in &self.facets {
            let p = f.map(|v| self.points[v as usize]);
            let n = crate::math::cross(sub(p[1], p[0]), sub(p[2], p[0]));
            for &v in f {
                normals[v as usize] = crate::math::add(normals[v as usize], n);
            }
        }
        normals
    }
}

fn one() -> f64 {
    1.0
}

fn yes() -> bool {
    true
}

/// What the scene needs to know of a surface shape before meshing.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceGeometry {
    /// Of the checked surface (for an MSH volume mesh, of its boundary), grain frame.
    pub descriptors: ShapeDescriptors,
    /// Largest distance of a vertex from the grain's origin (m).
    pub bounding_radius: f64,
    /// Facets of the surface as read and shortest edge (m).
    pub facets: usize,
    pub min_edge: f64,
    /// Exact (elements, nodes) of an MSH volume mesh used as is.
    pub volume_mesh: Option<(usize, usize)>,
    /// With `remesh`: the facets the remeshed surface will have (∫ dA / A(h)) and the
    /// smallest edge the size field asks for (m).
    pub remeshed: Option<(f64, f64)>,
}

impl SurfaceSpec {
    /// Metres per file unit, `None` for an unknown unit.
    pub fn unit_factor(&self) -> Option<f64> {
        match self.units.as_str() {
            "m" => Some(1.0),
            "cm" => Some(1e-2),
            "mm" => Some(1e-3),
            "um" | "µm" | "μm" => Some(1e-6),
            _ => None,
        }
    }

    /// Field checks (no file access). Fields are named below `surface.`.
    pub fn validate(&self) -> Result<(), MeshError> {
        let bad = |field: &str, message: String| MeshError::InvalidSpec {
            field: field.into(),
            message,
        };
        if Format::from_path(Path::new(&self.file)).is_none() {
            return Err(bad(
                "file",
                format!(
                    "'{}' has no known extension; use .stl, .obj or .msh",
                    crate::error::echo(&self.file)
                ),
            ));
        }
        if self.unit_factor().is_none() {
            return Err(bad(
                "units",
                format!(
                    "unknown unit '{}'; use m, cm, mm or um",
                    crate::error::echo(&self.units)
                ),
            ));
        }
        for (field, v) in [("seeding", self.seeding), ("scale", self.scale)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(
                    field,
                    format!("must be a finite number > 0, got {}", num(v)),
                ));
            }
        }
        for (i, z) in self.refine.iter().enumerate() {
            let f = |name: &str| format!("refine[{i}].{name}");
            if let Some(k) = (0..3).find(|&k| !z.point[k].is_finite()) {
                return Err(bad(&f(&format!("point[{k}]")), "must be finite".into()));
            }
            if !(z.seeding.is_finite() && z.seeding > 0.0 && z.seeding <= self.seeding) {
                return Err(bad(
                    &f("seeding"),
                    format!(
                        "must be > 0 and at most the shape's seeding {}, got {}",
                        num(self.seeding),
                        num(z.seeding)
                    ),
                ));
            }
            if !(z.radius.is_finite() && z.radius >= 0.0) {
                return Err(bad(
                    &f("radius"),
                    format!("must be a finite length ≥ 0, got {}", num(z.radius)),
                ));
            }
            let (lo, hi) = (super::sphere::MIN_GROWTH, super::sphere::MAX_GROWTH);
            if !(lo..=hi).contains(&z.growth) {
                return Err(bad(
                    &f("growth"),
                    format!("must be in [{lo}, {hi}], got {}", num(z.growth)),
                ));
            }
        }
        if let Some(c) = &self.curvature {
            if !self.remesh {
                return Err(bad(
                    "curvature",
                    "curvature sizing remeshes the surface; it needs remesh = true".into(),
                ));
            }
            if !(c.mr.is_finite() && c.mr > 0.0 && c.mr <= 0.5) {
                return Err(bad(
                    "curvature.mr",
                    format!("must be in (0, 0.5], got {}", num(c.mr)),
                ));
            }
            if !(c.min_seeding.is_finite() && c.min_seeding > 0.0 && c.min_seeding <= self.seeding)
            {
                return Err(bad(
                    "curvature.min_seeding",
                    format!(
                        "must be > 0 and at most the shape's seeding {}, got {}",
                        num(self.seeding),
                        num(c.min_seeding)
                    ),
                ));
            }
            let (lo, hi) = (super::sphere::MIN_GROWTH, super::sphere::MAX_GROWTH);
            if !(lo..=hi).contains(&c.growth) {
                return Err(bad(
                    "curvature.growth",
                    format!("must be in [{lo}, {hi}], got {}", num(c.growth)),
                ));
            }
        }
        if let Some(k) = (0..3).find(|&k| !self.rotation[k].is_finite()) {
            return Err(bad(
                &format!("rotation[{k}]"),
                format!("must be finite, got {}", num(self.rotation[k])),
            ));
        }
        Ok(())
    }

    /// Makes a relative `file` relative to the directory of `scene_file`.
    pub fn resolve_against(&mut self, scene_file: &Path) {
        let p = PathBuf::from(&self.file);
        if p.is_relative() {
            if let Some(dir) = scene_file.parent().filter(|d| !d.as_os_str().is_empty()) {
                self.file = dir.join(p).display().to_string();
            }
        }
    }

    fn factor(&self) -> f64 {
        self.unit_factor().unwrap_or(1.0) * self.scale
    }
}

/// A checked shape in the grain frame (metres, origin placed), before rotation.
#[derive(Debug, Clone)]
pub enum Prepared {
    Surface(Surface),
    Volume(TetMesh),
}

fn file_error(
    spec: &SurfaceSpec,
    item: impl Into<String>,
    message: impl Into<String>,
) -> MeshError {
    MeshError::File(InputError::new(&spec.file, item, message))
}

/// Reads, scales, repairs (when asked; `report` prints what changed on stderr), checks and
/// centres the shape. Returns it with the file's bytes (for the cache key).
pub fn prepare(spec: &SurfaceSpec, report: bool) -> Result<(Prepared, Vec<u8>), MeshError> {
    spec.validate()?;
    let bytes = std::fs::read(&spec.file)
        .map_err(|e| file_error(spec, "file", format!("cannot read the surface file: {e}")))?;
    let format = Format::from_path(Path::new(&spec.file)).unwrap_or(Format::Stl);
    let imported =
        formats::read(format, &bytes).map_err(|(item, msg)| file_error(spec, item, msg))?;
    let factor = spec.factor();
    let prepared = match imported {
        Imported::Surface(mut s) => {
            s.points.iter_mut().for_each(|p| *p = p.map(|c| c * factor));
            if spec.repair {
                let r = checks::repair(&mut s);
                if report && !r.is_empty() {
                    crate::error::report_line(format_args!("note: {}: repaired: {r}", spec.file));
                }
                // Drop the vertices merged away (TetGen would keep them as loose points).
                s = formats::surface_from_soup(
                    s.facets.iter().map(|f| f.map(|i| s.points[i as usize])),
                );
            }
            checks::check(&s).map_err(|(item, msg)| file_error(spec, item, msg))?;
            if spec.origin == SurfaceOrigin::Centroid {
                let c = ShapeDescriptors::of(&s).centroid;
                s.points.iter_mut().for_each(|p| *p = sub(*p, c));
            }
            Prepared::Surface(s)
        }
        Imported::Volume(mut m) => {
            m.nodes.iter_mut().for_each(|p| *p = p.map(|c| c * factor));
            super::validate(&m).map_err(|e| {
                file_error(
                    spec,
                    e.item(),
                    e.to_string()
                        .split_once(": ")
                        .map_or(e.to_string(), |x| x.1.to_string()),
                )
            })?;
            if spec.origin == SurfaceOrigin::Centroid {
                let c = ShapeDescriptors::of(&boundary_of(&m)).centroid;
                m.nodes.iter_mut().for_each(|p| *p = sub(*p, c));
            }
            Prepared::Volume(m)
        }
    };
    Ok((prepared, bytes))
}

fn boundary_of(m: &TetMesh) -> Surface {
    let s = super::extract_surface(m);
    Surface {
        points: m.nodes.clone(),
        facets: s.facets,
    }
}

/// Checks the shape and returns its geometry (used when the scene is loaded).
pub fn inspect(spec: &SurfaceSpec) -> Result<SurfaceGeometry, MeshError> {
    let (prepared, _) = prepare(spec, true)?;
    let (surface, volume_mesh) = match &prepared {
        Prepared::Surface(s) => (s.clone(), None),
        Prepared::Volume(m) => (boundary_of(m), Some((m.tets.len(), m.nodes.len()))),
    };
    let min_edge = surface
        .facets
        .iter()
        .flat_map(|f| (0..3).map(move |k| (f[k], f[(k + 1) % 3])))
        .map(|(a, b)| norm(sub(surface.points[a as usize], surface.points[b as usize])))
        .fold(f64::INFINITY, f64::min);
    let used = |i: usize| surface.facets.iter().any(|f| f.contains(&(i as u32)));
    let bounding_radius = match volume_mesh {
        Some(_) => surface
            .points
            .iter()
            .enumerate()
            .filter(|(i, _)| used(*i))
            .map(|(_, p)| norm(*p))
            .fold(0.0, f64::max),
        None => surface.points.iter().map(|p| norm(*p)).fold(0.0, f64::max),
    };
    let remeshed = (spec.remesh && volume_mesh.is_none()).then(|| {
        let field = zones::SizeField {
            seeding: spec.seeding,
            zones: &spec.refine,
        };
        let reference = remesh::Reference::new(&surface, field, spec.curvature.as_ref());
        (reference.expected_facets(), reference.smallest_size())
    });
    Ok(SurfaceGeometry {
        descriptors: ShapeDescriptors::of(&surface),
        bounding_radius,
        facets: surface.facets.len(),
        min_edge,
        volume_mesh,
        remeshed,
    })
}

/// Meshes the shape, through the on-disk cache of [`cache::cache_dir`].
pub fn mesh_surface(spec: &SurfaceSpec) -> Result<TetMesh, MeshError> {
    mesh_surface_cached(spec, cache::cache_dir().as_deref()).map(|(m, _)| m)
}

/// Meshes the shape with the cache in `cache_dir` (none: no cache); also says whether the
/// mesh came from the cache.
pub fn mesh_surface_cached(
    spec: &SurfaceSpec,
    cache_dir: Option<&Path>,
) -> Result<(TetMesh, bool), MeshError> {
    let (prepared, bytes) = prepare(spec, false)?;
    let (mut mesh, hit) = match prepared {
        Prepared::Volume(m) => (m, false),
        Prepared::Surface(s) => {
            let key = cache_key(spec, &bytes);
            match cache_dir.and_then(|d| cache::load(d, &key)) {
                Some(m) => (m, true),
                None => {
                    let m = fill(&s, spec)?;
                    if let Some(d) = cache_dir {
                        cache::store(d, &key, &m);
                    }
                    (m, false)
                }
            }
        }
    };
    rotate(&mut mesh.nodes, spec.rotation);
    Ok((mesh, hit))
}

/// The disk-cache key of a surface shape: mesher version, the file's length and hash, and
/// every meshing option.
fn cache_key(spec: &SurfaceSpec, bytes: &[u8]) -> String {
    format!(
        "mufe surface mesher {MESHER_VERSION}\nfile {} bytes fnv64 {:016x}\nseeding {:e}\nfactor {:e}\nrepair {}\norigin {:?}\n",
        bytes.len(),
        cache::fnv64(bytes),
        spec.seeding,
        spec.factor(),
        spec.repair,
        spec.origin
    ) + &if spec.refine.is_empty() {
        String::new()
    } else {
        format!("refine {}\n", serde_json::to_string(&spec.refine).unwrap_or_default())
    } + &format!(
        "remesh {}\ncurvature {}\n",
        spec.remesh,
        serde_json::to_string(&spec.curvature).unwrap_or_default()
    )
}

/// The executable that runs `mufe mesh-worker`, set by the `mufe` binary at start-up when
/// it is not an MPI rank; without it (library use, tests, MPI runs) shapes mesh in-process.
static WORKER_EXE: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();

/// Lets [`premesh_in_workers`] start `exe mesh-worker` processes.
pub fn enable_worker_processes(exe: PathBuf) {
    let _ = WORKER_EXE.set(exe);
}

/// Meshes the surface shapes of `specs` that are not in the disk cache yet in up to
/// `workers` `mufe mesh-worker` processes at once, each leaving its mesh in the cache for
/// the caller's serial pass, which then only loads them. Processes, not threads, because
/// TetGen keeps process-wide state. Returns how many shapes the workers meshed. A worker
/// that fails is ignored: the serial pass meets the same error and reports it in context.
/// Does nothing without a cache, without [`enable_worker_processes`], or for fewer than
/// two uncached shapes or workers. A corrupt entry counts as cached here; the serial pass
/// finds it invalid and re-meshes in-process.
pub fn premesh_in_workers(specs: &[&SurfaceSpec], workers: usize) -> usize {
    let (Some(exe), Some(dir)) = (WORKER_EXE.get(), cache::cache_dir()) else {
        return 0;
    };
    let mut missing: Vec<&SurfaceSpec> = Vec::new();
    let mut keys = std::collections::BTreeSet::new();
    for spec in specs {
        let Ok(bytes) = std::fs::read(&spec.file) else {
            continue;
        };
        if Format::from_path(Path::new(&spec.file)) == Some(Format::Msh) {
            continue; // may be a volume mesh, used as is
        }
        let key = cache_key(spec, &bytes);
        if !cache::contains(&dir, &key) && keys.insert(key) {
            missing.push(spec);
        }
    }
    if missing.len() < 2 || workers < 2 {
        return 0;
    }
    let mut running: std::collections::VecDeque<std::process::Child> = Default::default();
    let mut meshed = 0;
    let mut finish = |child: std::process::Child| {
        if child.wait_with_output().is_ok_and(|o| o.status.success()) {
            meshed += 1;
        }
    };
    for spec in missing {
        if running.len() == workers {
            if let Some(child) = running.pop_front() {
                finish(child);
            }
        }
        let Ok(json) = serde_json::to_string(spec) else {
            continue;
        };
        let child = std::process::Command::new(exe)
            .arg("mesh-worker")
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn();
        if let Ok(mut child) = child {
            if let Some(mut stdin) = child.stdin.take() {
                let _ = std::io::Write::write_all(&mut stdin, json.as_bytes());
            }
            running.push_back(child);
        }
    }
    for child in running {
        finish(child);
    }
    meshed
}

/// `mufe mesh-worker`: meshes the JSON surface spec read from stdin into the disk cache.
pub fn run_mesh_worker() -> Result<(), String> {
    let mut text = String::new();
    std::io::Read::read_to_string(&mut std::io::stdin(), &mut text).map_err(|e| e.to_string())?;
    let spec: SurfaceSpec = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let dir = cache::cache_dir().ok_or("no mesh cache directory")?;
    mesh_surface_cached(&spec, Some(&dir))
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// Remeshes the surface to the size field (`seeding`, finer in the zones and where curved;
/// or, with `remesh = false`, subdivides it to edges ≤ the size) and fills it with tets,
/// seeding the interior with the lattice of [`zones::interior_points`].
fn fill(s: &Surface, spec: &SurfaceSpec) -> Result<TetMesh, MeshError> {
    let seeding = spec.seeding;
    let field = zones::SizeField {
        seeding,
        zones: &spec.refine,
    };
    let too_large = || MeshError::TooLarge {
        field: "seeding".into(),
        limit: MAX_FACETS,
    };
    let subdivided = || refine::subdivide_to(s, |x| field.at(x), MAX_FACETS).ok_or_else(too_large);
    let fine = if spec.remesh {
        let reference = remesh::Reference::new(s, field, spec.curvature.as_ref());
        if reference.expected_facets() > MAX_FACETS as f64 {
            return Err(too_large());
        }
        let remeshed = remesh::remesh(s, &reference);
        match checks::check(&remeshed) {
            Ok(()) => remeshed,
            Err((place, defect)) => {
                // never expected; the file's own facets are a valid surface to mesh
                crate::error::report_line(format_args!(
                    "warning: {}: remeshing gave an invalid surface ({place}: {defect}); meshing the file's facets subdivided instead",
                    spec.file
                ));
                subdivided()?
            }
        }
    } else {
        subdivided()?
    };
    // TetGen's tolerances are relative and its volume bound goes through text: work at
    // order-one coordinates.
    let size = fine
        .points
        .iter()
        .map(|p| norm(*p))
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let mut points: Vec<[f64; 3]> = fine.points.iter().map(|p| p.map(|c| c / size)).collect();
    points.extend(
        zones::interior_points(&fine, field)
            .into_iter()
            .map(|p| p.map(|c| c / size)),
    );
    // no volume bound: the lattice sets the interior size, and a bound would split every
    // surface facet with area^1.5 above it (most facets of edge ≈ seeding)
    let mut mesh = tetrahedralize(
        &points,
        &fine.facets,
        &[],
        super::sphere::RADIUS_EDGE_RATIO,
        None,
    )?;
    // TetGen's slivers set the explicit step: move the interior nodes as the sphere
    // mesher does (the surface stays exactly as checked)
    super::improve::improve_off_surface(&mut mesh);
    mesh.nodes.iter_mut().for_each(|p| *p = p.map(|c| c * size));
    super::validate(&mesh)?;
    Ok(mesh)
}

/// Axis-aligned bounding box (low and high corners).
pub fn bounding_box(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// Rotates points by the axis-angle vector `w` (Rodrigues).
pub fn rotate(points: &mut [[f64; 3]], w: [f64; 3]) {
    let angle = norm(w);
    if angle == 0.0 {
        return;
    }
    let r = nalgebra::Rotation3::new(nalgebra::Vector3::from(w));
    for p in points.iter_mut() {
        let q = r * nalgebra::Vector3::from(*p);
        *p = [q.x, q.y, q.z];
    }
}
