//! `mufe import`: a label image → one surface grain per label → a scene.
//!
//! Pipeline: voxel size (command line, else the header's spacing with its unit) →
//! [`contour::extract`] → [`contour::smooth`] → per grain, [`decimate::decimate`] with its
//! contact faces locked → an optional gap (every vertex moved inward by half of it) →
//! surface checks → one joint TetGen run (`mesh::joint`; without a gap) → overlap of every
//! pair of grains whose boxes meet. Each grain is written as a Gmsh volume mesh (an OBJ
//! surface with a gap), in metres at full precision relative to its volume centroid, its
//! `centre` in the scene, so the touching faces of two grains land on the same points in
//! the run to within a rounding of the coordinates.

use std::fmt::Write as _;
use std::path::Path;

use rayon::prelude::*;

use super::contour::{extract, smooth};
use super::decimate::decimate;
use super::overlap::{boxes_meet, overlap_of, PairOverlap};
use super::LabelImage;
use crate::error::{num, InputError};
use crate::math::{norm, scale, sub};
use crate::mesh::import::checks::{check, signed_volume};
use crate::mesh::import::formats::{surface_from_soup, write_msh_volume, write_obj};
use crate::mesh::import::{ShapeDescriptors, Surface};
use crate::mesh::joint::mesh_touching;
use crate::mesh::TetMesh;

/// Choices of `mufe import`.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportOptions {
    /// Voxel edge (m); overrides the header's spacing.
    pub voxel_size: Option<f64>,
    /// Surface edge to coarsen to (m); default [`DEFAULT_SEEDING_VOXELS`] voxels.
    pub seeding: Option<f64>,
    /// Taubin smoothing passes.
    pub smoothing: usize,
    /// Gap left between touching grains (m); 0: their faces meet.
    pub gap: f64,
    /// Labels with fewer voxels are left out (and listed).
    pub min_voxels: usize,
}

/// Smallest gap in voxel edges: grains with a gap are meshed one by one, and TetGen's
/// Steiner points on one grain's face must not start inside the other's curved contact
/// surface, which bulges off its triangles by up to a few hundredths of a voxel.
pub const MIN_GAP_VOXELS: f64 = 0.1;

/// Vertices within this many voxel edges of a contact face are left as extracted by the
/// decimation: coarsening next to a contact could push one grain's free surface through
/// its neighbour's.
pub const FROZEN_BAND_VOXELS: f64 = 1.5;

/// Default seeding in voxel edges.
pub const DEFAULT_SEEDING_VOXELS: f64 = 2.0;

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            voxel_size: None,
            seeding: None,
            smoothing: 10,
            gap: 0.0,
            min_voxels: 27,
        }
    }
}

/// One imported grain, in scene coordinates (m).
#[derive(Debug, Clone)]
pub struct ImportedGrain {
    pub label: u32,
    pub voxels: usize,
    /// Voxel count × voxel volume (m³).
    pub voxel_volume: f64,
    pub surface: Surface,
    /// Vertices on a face shared with another grain.
    pub shared: usize,
    pub descriptors: ShapeDescriptors,
    /// Its tets, from the joint mesh of all grains (without a gap); `None` with a gap (the
    /// surface is meshed by the scene's surface pipeline).
    pub mesh: Option<TetMesh>,
}

/// Overlap between two grains whose boxes meet.
#[derive(Debug, Clone, Copy)]
pub struct PairReport {
    pub labels: (u32, u32),
    pub first_in_second: PairOverlap,
    pub second_in_first: PairOverlap,
}

/// What an import made.
#[derive(Debug, Clone)]
pub struct Imported {
    pub grains: Vec<ImportedGrain>,
    pub pairs: Vec<PairReport>,
    /// Labels left out: (label, voxels).
    pub skipped: Vec<(u32, usize)>,
    /// Voxel edges used (m).
    pub spacing: [f64; 3],
    pub seeding: f64,
    /// Wall time of each stage (name, s).
    pub timings: Vec<(&'static str, f64)>,
}

/// Voxel spacing (m) and origin (m) of an image, from the options or the header.
pub fn spacing_of(
    image: &LabelImage,
    file: &str,
    opts: &ImportOptions,
) -> Result<([f64; 3], [f64; 3]), InputError> {
    let unit = image.spacing.and_then(|s| s.metres_per_unit);
    let origin = image.origin.map(|c| c * unit.unwrap_or(0.0));
    if let Some(s) = opts.voxel_size {
        return Ok(([s; 3], origin));
    }
    match image.spacing {
        None => Err(InputError::new(
            file,
            "spacings",
            "the header gives no voxel spacing; pass --voxel-size (m)",
        )),
        Some(s) => match s.metres_per_unit {
            None => Err(InputError::new(
                file,
                "space units",
                format!(
                    "the header gives spacings {:?} without a unit; pass --voxel-size (m)",
                    s.values
                ),
            )),
            Some(u) => Ok((s.values.map(|v| v * u), origin)),
        },
    }
}

/// Runs the pipeline on a read image. `file` names the image in errors.
pub fn import_labels(
    image: &LabelImage,
    file: &str,
    opts: &ImportOptions,
) -> Result<Imported, InputError> {
    let (spacing, origin) = spacing_of(image, file, opts)?;
    let voxel = spacing.iter().copied().fold(f64::INFINITY, f64::min);
    let seeding = opts.seeding.unwrap_or(DEFAULT_SEEDING_VOXELS * voxel);
    let gap_ok = opts.gap == 0.0 || (opts.gap >= MIN_GAP_VOXELS * voxel && opts.gap < 0.5 * voxel);
    if !gap_ok {
        return Err(InputError::new(
            "<command line>",
            "--gap",
            format!(
                "must be 0 or from {} to below half a voxel ({} m), got {}",
                num(MIN_GAP_VOXELS * voxel),
                num(0.5 * voxel),
                num(opts.gap)
            ),
        ));
    }
    let mut timings = Vec::new();
    let mut clock = std::time::Instant::now();
    let mut lap = |name: &'static str, timings: &mut Vec<(&'static str, f64)>| {
        timings.push((name, clock.elapsed().as_secs_f64()));
        clock = std::time::Instant::now();
    };
    let mut contours = extract(image, spacing, origin);
    lap("extract", &mut timings);
    smooth(&mut contours, opts.smoothing);
    lap("smooth", &mut timings);
    let voxel_volume = spacing[0] * spacing[1] * spacing[2];
    let (kept, skipped): (Vec<_>, Vec<_>) = contours
        .grains
        .iter()
        .partition(|g| g.voxels >= opts.min_voxels);
    let mut grains: Vec<ImportedGrain> = kept
        .par_iter()
        .map(|g| {
            let (surface, shared) = compact(&contours.points, &contours.shared, &g.facets);
            let frozen = near_any(&surface.points, &shared, FROZEN_BAND_VOXELS * voxel);
            let (mut surface, _) = decimate(&surface, &frozen, seeding);
            if opts.gap > 0.0 {
                offset_inward(&mut surface, 0.5 * opts.gap);
            }
            check(&surface).map_err(|(item, message)| {
                InputError::new(
                    file,
                    format!("label {}", g.label),
                    format!("its surface fails the checks at {item}: {message} (a label in separate pieces, or too thin for the voxel size?)"),
                )
            })?;
            Ok(ImportedGrain {
                label: g.label,
                voxels: g.voxels,
                voxel_volume: g.voxels as f64 * voxel_volume,
                shared: shared.iter().filter(|&&l| l).count(),
                descriptors: ShapeDescriptors::of(&surface),
                surface,
                mesh: None,
            })
        })
        .collect::<Result<_, InputError>>()?;
    lap("decimate and check", &mut timings);
    if opts.gap == 0.0 {
        let inside: Vec<[f64; 3]> = {
            let deepest = image.deepest_voxels();
            grains
                .iter()
                .map(|g| {
                    let v = deepest[&g.label];
                    [0, 1, 2].map(|a| origin[a] + spacing[a] * v[a] as f64)
                })
                .collect()
        };
        let meshes = mesh_jointly(&grains, &inside, seeding).map_err(|e| {
            InputError::new(
                file,
                "labels",
                format!("meshing the grains together failed: {e}"),
            )
        })?;
        for (g, m) in grains.iter_mut().zip(meshes) {
            g.mesh = Some(m);
        }
        lap("mesh (TetGen, joint)", &mut timings);
    }
    let tolerance = 1e-9 * voxel;
    let candidates: Vec<(usize, usize)> = (0..grains.len())
        .flat_map(|i| (i + 1..grains.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| boxes_meet(&grains[i].surface, &grains[j].surface, voxel))
        .collect();
    let pairs = candidates
        .par_iter()
        .map(|&(i, j)| PairReport {
            labels: (grains[i].label, grains[j].label),
            first_in_second: overlap_of(&grains[i].surface, &grains[j].surface, tolerance),
            second_in_first: overlap_of(&grains[j].surface, &grains[i].surface, tolerance),
        })
        .collect();
    lap("overlap", &mut timings);
    Ok(Imported {
        grains,
        pairs,
        skipped: skipped.iter().map(|g| (g.label, g.voxels)).collect(),
        spacing,
        seeding,
        timings,
    })
}

/// One TetGen run over all grains' surfaces, a shared face once: shared vertices are
/// locked through decimation, so they are found by their exact coordinates.
fn mesh_jointly(
    grains: &[ImportedGrain],
    inside: &[[f64; 3]],
    seeding: f64,
) -> Result<Vec<TetMesh>, crate::mesh::MeshError> {
    let union = surface_from_soup(grains.iter().flat_map(|g| {
        g.surface
            .facets
            .iter()
            .map(|f| f.map(|v| g.surface.points[v as usize]))
    }));
    let mut seen = std::collections::HashSet::new();
    let facets: Vec<[u32; 3]> = union
        .facets
        .into_iter()
        .filter(|f| {
            let mut key = *f;
            key.sort_unstable();
            seen.insert(key)
        })
        .collect();
    mesh_touching(&union.points, &facets, inside, seeding)
}

/// Vertices within `band` of a vertex flagged in `of` (the flagged ones included).
fn near_any(points: &[[f64; 3]], of: &[bool], band: f64) -> Vec<bool> {
    let cell = |p: [f64; 3]| p.map(|c| (c / band).floor() as i64);
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> = Default::default();
    for (i, p) in points.iter().enumerate().filter(|(i, _)| of[*i]) {
        grid.entry(cell(*p)).or_default().push(i);
    }
    points
        .iter()
        .map(|p| {
            let c = cell(*p);
            (-1..=1).any(|dx| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dz| {
                        grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz])
                            .is_some_and(|list| {
                                list.iter().any(|&j| norm(sub(points[j], *p)) <= band)
                            })
                    })
                })
            })
        })
        .collect()
}

/// A grain's own surface from the shared vertex table, with its shared flags.
fn compact(points: &[[f64; 3]], shared: &[bool], facets: &[[u32; 3]]) -> (Surface, Vec<bool>) {
    let (points, facets, old) = crate::mesh::compact_cells(points, facets.iter().copied());
    let locked = old.iter().map(|&v| shared[v as usize]).collect();
    (Surface { points, facets }, locked)
}

/// Moves every vertex inward along its area-weighted normal by `d`.
fn offset_inward(s: &mut Surface, d: f64) {
    let normals = s.vertex_normals();
    for (p, n) in s.points.iter_mut().zip(&normals) {
        let l = norm(*n);
        if l > 0.0 {
            *p = sub(*p, scale(*n, d / l));
        }
    }
}

/// Writes `<scene stem>_grains/label_<L>.msh` (the joint volume meshes; `.obj` surfaces
/// with a gap) beside the scene and the scene itself;
/// `command` is the command line recorded in its header.
pub fn write_scene(scene: &Path, imported: &Imported, command: &str) -> std::io::Result<()> {
    let stem = scene
        .file_stem()
        .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let dir_name = format!("{stem}_grains");
    let dir = scene.parent().unwrap_or(Path::new(".")).join(&dir_name);
    std::fs::create_dir_all(&dir)?;
    let mut t = String::new();
    let touching = imported
        .pairs
        .iter()
        .filter(|p| p.first_in_second.touching > 0 || p.second_in_first.touching > 0)
        .count();
    let _ = writeln!(t, "# Imported by `{command}`");
    let _ = writeln!(
        t,
        "# {} grains from a label image of voxels {:e} × {:e} × {:e} m; surfaces coarsened to {:e} m.",
        imported.grains.len(),
        imported.spacing[0],
        imported.spacing[1],
        imported.spacing[2],
        imported.seeding
    );
    let _ = writeln!(
        t,
        "# {touching} pairs of grains touch in the image: their contact faces coincide, so the\n# run starts with those contacts stress-free. Edit the material, friction and duration,\n# and add walls, loads or stages for your study (docs/INPUT.md)."
    );
    let _ = writeln!(t, "\n[simulation]\nduration = 1.0e-4   # s\n");
    let _ = writeln!(
        t,
        "[materials.grain]   # quartz: edit\nyoungs_modulus = 7.0e10   # Pa\npoisson_ratio = 0.17      # –\ndensity = 2650.0          # kg/m³\n"
    );
    let _ = writeln!(t, "[contact]\nfriction = 0.5   # –");
    for g in &imported.grains {
        let c = g.descriptors.centroid;
        let mut relative = g.surface.clone();
        relative.points.iter_mut().for_each(|p| *p = sub(*p, c));
        let name = match &g.mesh {
            Some(m) => {
                let name = format!("label_{}.msh", g.label);
                let mut relative = m.clone();
                relative.nodes.iter_mut().for_each(|p| *p = sub(*p, c));
                let mut f = std::io::BufWriter::new(std::fs::File::create(dir.join(&name))?);
                write_msh_volume(&relative, &mut f)?;
                std::io::Write::flush(&mut f)?;
                name
            }
            None => {
                let name = format!("label_{}.obj", g.label);
                let mut f = std::io::BufWriter::new(std::fs::File::create(dir.join(&name))?);
                write_obj(&relative, &mut f)?;
                std::io::Write::flush(&mut f)?;
                name
            }
        };
        let _ = writeln!(
            t,
            "\n[[grains]]\nname = \"label_{}\"\nmaterial = \"grain\"\ncentre = [{:e}, {:e}, {:e}]   # m: volume centroid\nshape = {{ surface = {{ file = \"{dir_name}/{name}\", units = \"m\", seeding = {:e}, origin = \"file\" }} }}",
            g.label, c[0], c[1], c[2], imported.seeding
        );
    }
    std::fs::write(scene, t)
}

/// The lines `mufe import` prints: one per grain, one per touching or overlapping pair.
pub fn report(imported: &Imported) -> String {
    let mut t = String::new();
    for g in &imported.grains {
        let v = signed_volume(&g.surface);
        let _ = writeln!(
            t,
            "label {}: {} voxels ({:.4e} m³); surface {} facets, {} vertices on contact faces;{} {:+.2} % from the voxels' volume; {}",
            g.label,
            g.voxels,
            g.voxel_volume,
            g.surface.facets.len(),
            g.shared,
            g.mesh.as_ref().map_or(String::new(), |m| format!(" {} tets, {} nodes;", m.tets.len(), m.nodes.len())),
            100.0 * (v / g.voxel_volume - 1.0),
            g.descriptors
        );
    }
    for (label, voxels) in &imported.skipped {
        let _ = writeln!(
            t,
            "label {label}: {voxels} voxels, below --min-voxels: left out"
        );
    }
    let mut overlapping = 0;
    for p in &imported.pairs {
        let (a, b) = (p.first_in_second, p.second_in_first);
        if a.touching + b.touching + a.inside + b.inside == 0 {
            continue;
        }
        overlapping += usize::from(a.inside + b.inside > 0);
        let _ = writeln!(
            t,
            "pair {}–{}: {} + {} vertices on the other's surface; overlap: {} + {} vertices inside the other, deepest {:.3e} m",
            p.labels.0,
            p.labels.1,
            a.touching,
            b.touching,
            a.inside,
            b.inside,
            a.max_depth.max(b.max_depth)
        );
    }
    let _ = writeln!(
        t,
        "{} grains; {} pairs with vertices inside each other",
        imported.grains.len(),
        overlapping
    );
    let stages: Vec<String> = imported
        .timings
        .iter()
        .map(|(name, s)| format!("{name} {s:.2} s"))
        .collect();
    let _ = writeln!(t, "wall time: {}", stages.join(", "));
    t
}

/// `mufe import LABELS --out SCENE`: checks the options, reads and imports the image,
/// prints the report, writes the grains and the scene (nothing is written on an error).
pub fn import_command(
    labels: &Path,
    scene: &Path,
    opts: &ImportOptions,
) -> Result<(), crate::error::MufeError> {
    let cli = |arg: &str, why: String| InputError::new("<command line>", arg, why);
    for (arg, v) in [
        ("--voxel-size", opts.voxel_size),
        ("--seeding", opts.seeding),
    ] {
        if let Some(v) = v.filter(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(cli(
                arg,
                format!("must be a finite length > 0 (m), got {}", num(v)),
            )
            .into());
        }
    }
    if opts.smoothing > 1000 {
        return Err(cli(
            "--smoothing",
            format!("must be 0 … 1000, got {}", opts.smoothing),
        )
        .into());
    }
    if scene.is_dir() || scene.extension().is_none_or(|e| e != "toml") {
        return Err(cli(
            "--out",
            format!(
                "'{}' must be a .toml scene file",
                crate::error::echo(&scene.display().to_string())
            ),
        )
        .into());
    }
    let file = labels.display().to_string();
    let image = super::tiff::read_label_image(labels)?;
    let imported = import_labels(&image, &file, opts)?;
    if imported.grains.is_empty() {
        return Err(
            InputError::new(&file, "data", "no label with at least --min-voxels voxels").into(),
        );
    }
    print!("{}", report(&imported));
    let args: Vec<String> = std::env::args().collect();
    write_scene(scene, &imported, &args.join(" ")).map_err(|e| {
        crate::error::MufeError::Io(format!("{}: cannot write the scene: {e}", scene.display()))
    })?;
    println!(
        "wrote {} and {} grain files",
        scene.display(),
        imported.grains.len()
    );
    Ok(())
}
