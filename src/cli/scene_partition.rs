//! `mufe partition`: the METIS partition of a scene's grains, without running it.

use super::guards::{estimate_and_guard, load};
use crate::error::{InputError, MufeError};
use crate::scene::LoadedScene;
use std::path::PathBuf;

/// What the partitioner is told about one grain, and whether its counts were estimated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScenePartitionGrain {
    pub info: partition::GrainInfo,
    /// `true` when `elements`/`surface_nodes` are estimates from the shape (no mesh built).
    pub estimated: bool,
}

/// Volume of a regular tetrahedron of edge `h` (m³).
fn regular_tet_volume(h: f64) -> f64 {
    h * h * h / (6.0 * std::f64::consts::SQRT_2)
}

/// Estimated (elements, surface nodes) of a sphere mesh without meshing it: the ball's
/// volume over the volume of a regular tet of the nominal edge (per region for graded
/// meshes), and the sphere's area over the area per node of an equilateral surface
/// triangulation (two triangles per node: 4πR² / (√3/2 · h²)). Within a few % of the
/// mesher for uniform and graded spheres. `None` for locally refined spheres.
fn estimate_sphere_counts(s: &crate::mesh::SphereMeshSpec) -> Option<(usize, usize)> {
    if !s.refine.is_empty() {
        return None;
    }
    let ball = |r: f64| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let elements = match &s.graded {
        None => ball(s.radius) / regular_tet_volume(s.seeding),
        Some(g) => {
            let core = s.radius - g.band_depth;
            (ball(s.radius) - ball(core)) / regular_tet_volume(s.seeding)
                + ball(core) / regular_tet_volume(g.core_seeding)
        }
    };
    let surface_nodes = 4.0 * std::f64::consts::PI * s.radius * s.radius
        / (0.5 * 3f64.sqrt() * s.seeding * s.seeding);
    Some((
        elements.ceil().max(1.0) as usize,
        surface_nodes.ceil().max(4.0) as usize,
    ))
}

/// The grain list of a scene for the partitioner: bounding sphere from the shape (sphere:
/// its radius about `centre`; block: half its diagonal about its middle), element and
/// surface-node counts exact for blocks, estimated for uniform and graded spheres, and
/// from a mesh (built once per distinct shape) for locally refined spheres or when
/// `exact` is set.
pub fn scene_partition_grains(
    loaded: &LoadedScene,
    exact: bool,
) -> Result<Vec<ScenePartitionGrain>, InputError> {
    use crate::scene::ShapeSpec;
    use std::collections::BTreeMap;
    let mut meshed: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    let mut out = Vec::with_capacity(loaded.scene.grains.len());
    for (i, g) in loaded.scene.grains.iter().enumerate() {
        let (centre, bounding_radius) = match &g.shape {
            ShapeSpec::Sphere(s) => (g.centre, s.radius),
            ShapeSpec::Block(b) => {
                let half = b.size.map(|x| 0.5 * x);
                (
                    [
                        g.centre[0] + half[0],
                        g.centre[1] + half[1],
                        g.centre[2] + half[2],
                    ],
                    (half[0] * half[0] + half[1] * half[1] + half[2] * half[2]).sqrt(),
                )
            }
            ShapeSpec::Surface(s) => (
                g.centre,
                s.geometry.as_ref().map_or(0.0, |x| x.bounding_radius),
            ),
        };
        let estimate = match &g.shape {
            ShapeSpec::Block(b) => {
                let [nx, ny, nz] = b.divisions;
                let all = (nx + 1) * (ny + 1) * (nz + 1);
                let inner = nx.saturating_sub(1) * ny.saturating_sub(1) * nz.saturating_sub(1);
                Some((6 * nx * ny * nz, all - inner))
            }
            ShapeSpec::Sphere(s) if !exact => estimate_sphere_counts(s),
            ShapeSpec::Sphere(_) => None,
            ShapeSpec::Surface(s) => s
                .geometry
                .as_ref()
                .and_then(|x| x.volume_mesh)
                .map(|(e, n)| (e, n / 4)),
        };
        // Blocks are exact from the formula; only spheres count as estimated.
        let estimated = estimate.is_some() && matches!(g.shape, ShapeSpec::Sphere(_));
        let (elements, surface_nodes) = match estimate {
            Some(c) => c,
            None => {
                let key = serde_json::to_string(&g.shape).unwrap_or_default();
                match meshed.get(&key) {
                    Some(c) => *c,
                    None => {
                        let m = crate::model::mesh_shape(&g.shape)
                            .map_err(|e| e.for_grain(&loaded.path, i))?;
                        let c = (m.tets.len(), crate::mesh::extract_surface(&m).nodes.len());
                        meshed.insert(key, c);
                        c
                    }
                }
            }
        };
        out.push(ScenePartitionGrain {
            info: partition::GrainInfo {
                centre,
                bounding_radius,
                elements,
                surface_nodes,
            },
            estimated,
        });
    }
    Ok(out)
}

/// The forward halo `mufe run` would send per step for the partition `owner` (the run's
/// ghost margin, not the grain graph's): whole ghost surfaces against contact zones.
fn print_contact_zone_halo(loaded: &LoadedScene, owner: &[u32]) -> Result<(), MufeError> {
    let global = crate::model::GlobalMesh::build(loaded)?;
    let nodes = crate::model::global::halo_nodes_per_rank(&global, &loaded.scene, owner);
    let bytes = crate::domain::halo::VALUES_PER_NODE as u64 * 8;
    let max = |i: usize| nodes.iter().map(|n| n[i] * bytes).max().unwrap_or(0);
    let total = |i: usize| nodes.iter().map(|n| n[i] * bytes).sum::<u64>();
    println!(
        "forward halo of mufe run (x, v of ghost surface nodes; ghost margin {:.4e} m): whole surfaces {:.3} MB/step max per part ({:.3} MB all parts), contact zones {:.3} MB max ({:.3} MB all, {:.0} % of whole)",
        crate::model::global::ghost_margin(&global),
        max(0) as f64 / 1e6,
        total(0) as f64 / 1e6,
        max(1) as f64 / 1e6,
        total(1) as f64 / 1e6,
        100.0 * total(1) as f64 / total(0).max(1) as f64
    );
    Ok(())
}

pub(super) fn partition_command(
    scene: &std::path::Path,
    set: &[String],
    parts: usize,
    out: Option<&std::path::Path>,
    margin: Option<f64>,
    exact: bool,
    force: bool,
) -> Result<(), MufeError> {
    let file = scene.display().to_string();
    if parts == 0 {
        return Err(InputError::new("<command line>", "--parts", "must be ≥ 1, got 0").into());
    }
    if let Some(m) = margin {
        if !m.is_finite() || m < 0.0 {
            return Err(InputError::new(
                "<command line>",
                "--margin",
                format!("must be a finite length ≥ 0 (m), got {m}"),
            )
            .into());
        }
    }
    if let Some(path) = out {
        if path.is_dir() {
            return Err(InputError::new(
                "<command line>",
                "--out",
                format!(
                    "'{}' is a directory; give a file name",
                    crate::error::echo(&path.display().to_string())
                ),
            )
            .into());
        }
    }
    let loaded = load(scene, set)?;
    // Partitioning meshes refined spheres (all with --exact): same memory guard as check.
    estimate_and_guard(&loaded, force, None)?;
    let n = loaded.scene.grains.len();
    if parts > n {
        return Err(InputError::new(
            &file,
            "--parts",
            format!("cannot partition {n} grain{} into {parts} parts: every part needs at least one grain (use --parts ≤ {n})", if n == 1 { "" } else { "s" }),
        )
        .into());
    }
    let grains = scene_partition_grains(&loaded, exact)?;
    let infos: Vec<partition::GrainInfo> = grains.iter().map(|g| g.info).collect();
    let margin = margin.unwrap_or_else(|| {
        let mut r: Vec<f64> = infos.iter().map(|g| g.bounding_radius).collect();
        r.sort_by(f64::total_cmp);
        0.1 * r[r.len() / 2]
    });
    let cost = partition::CostModel::default();
    let graph = partition::GrainGraph::try_build(&infos, margin, &cost)
        .map_err(|e| InputError::new(&file, "grains", e.to_string()))?;
    let part = partition::partition(&graph, parts, 0).map_err(|e| match e {
        partition::PartitionError::InvalidPartCount { .. } => {
            InputError::new(&file, "--parts", e.to_string()).into()
        }
        other => MufeError::Run(format!("{file}: partitioning failed: {other}")),
    })?;
    let quality = partition::metrics(&graph, &infos, &part, parts)
        .map_err(|e| MufeError::Run(format!("{file}: partition metrics failed: {e}")))?;

    let estimated = grains.iter().filter(|g| g.estimated).count();
    let elements: usize = infos.iter().map(|g| g.elements).sum();
    let surface: usize = infos.iter().map(|g| g.surface_nodes).sum();
    println!("scene: {}", loaded.path);
    println!(
        "grains: {n}; elements {elements}, surface nodes {surface}{}",
        if estimated > 0 {
            format!(" ({estimated} grains estimated from their shape; --exact meshes them)")
        } else {
            String::new()
        }
    );
    println!(
        "grain graph: {} contact edges (bounding spheres within margin {margin:.4e} m); cost per step = {} × elements + {} × surface nodes",
        graph.n_edges(),
        cost.cost_per_element,
        cost.cost_per_surface_node
    );
    println!("{quality}");
    if exact && crate::driver::rank::trims_ghosts(&loaded) {
        print_contact_zone_halo(&loaded, &part)?;
    }
    if let Some(path) = out {
        // Write beside the target and rename, so an existing file is never left half-written.
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".tmp");
        let tmp = PathBuf::from(tmp);
        let written = partition::write_partition(&tmp, &part)
            .map_err(|e| match e {
                partition::PartitionError::Io { message, .. } => message,
                other => other.to_string(),
            })
            .and_then(|()| std::fs::rename(&tmp, path).map_err(|e| e.to_string()));
        if let Err(message) = written {
            let _ = std::fs::remove_file(&tmp);
            return Err(MufeError::Io(format!(
                "{}: cannot write partition file: {message}",
                path.display()
            )));
        }
        println!("partition written to {}", path.display());
    }
    Ok(())
}
