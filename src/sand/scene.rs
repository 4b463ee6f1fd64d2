//! Writes a virtual sand: one binary STL per grain (in mm) and `scene.toml` placing the
//! grains on a loose grid (centres 1.5 bounding diameters apart) between a bottom and a
//! top wall, under gravity, which `mufe check` accepts as written.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::{grain_surface, GrainShape, SandParams};
use crate::math::norm;
use crate::mesh::import::formats::write_stl_binary;

/// Writes grain `i` of the sand as `dir/grain_NNN.stl` (binary, millimetres: sizes of order
/// one, well resolved in f32); returns its surface in metres and the file name.
pub(super) fn write_grain_stl(
    dir: &Path,
    p: &SandParams,
    i: usize,
) -> std::io::Result<(crate::mesh::import::Surface, String)> {
    let s = grain_surface(p, i);
    let mut mm = s.clone();
    mm.points.iter_mut().for_each(|x| *x = x.map(|c| c * 1e3));
    let name = format!("grain_{i:03}.stl");
    let mut f = std::io::BufWriter::new(std::fs::File::create(dir.join(&name))?);
    write_stl_binary(&mm, &mut f)?;
    Ok((s, name))
}

/// Writes the grains and the scene into `dir` (created if needed); returns the scene path.
pub fn write_sand(dir: &Path, p: &SandParams) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let mut names = Vec::with_capacity(p.grains);
    let mut bound: f64 = 0.0;
    for i in 0..p.grains {
        let (s, name) = write_grain_stl(dir, p, i)?;
        bound = bound.max(s.points.iter().map(|x| norm(*x)).fold(0.0, f64::max));
        names.push(name);
    }
    let per_row = (p.grains as f64).sqrt().ceil() as usize;
    let spacing = 3.0 * bound;
    let layer = per_row * per_row;
    let layers = p.grains.div_ceil(layer);
    let top = (layers as f64 - 1.0) * spacing + 2.4 * bound;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Virtual sand written by `mufe sand --grains {} --seed {} --elongation {} --flatness {} --roughness {} --size {:e} --seeding {:e}`",
        p.grains, p.seed, p.elongation, p.flatness, p.roughness, p.size, p.seeding
    );
    let _ = writeln!(
        t,
        "[simulation]\nduration = 2.0e-3\ngravity = [0.0, 0.0, -9.81]\ndeformation_damping = 0.0\n"
    );
    let _ = writeln!(
        t,
        "[materials.quartz]\nyoungs_modulus = 7.0e10\npoisson_ratio = 0.17\ndensity = 2650.0\n"
    );
    let _ = writeln!(t, "[contact]\nfriction = 0.3\n");
    for (i, name) in names.iter().enumerate() {
        let (k, j, l) = (i % per_row, (i / per_row) % per_row, i / layer);
        let c = [
            k as f64 * spacing,
            j as f64 * spacing,
            1.2 * bound + l as f64 * spacing,
        ];
        let _ = writeln!(
            t,
            "[[grains]]\nname = \"g{i}\"\nmaterial = \"quartz\"\ncentre = [{:e}, {:e}, {:e}]\nshape = {{ surface = {{ file = \"{name}\", units = \"mm\", seeding = {:e} }} }}\n",
            c[0], c[1], c[2], p.seeding
        );
    }
    let _ = writeln!(
        t,
        "[[walls]]\nname = \"bottom\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nfriction = 0.3\n"
    );
    let _ = writeln!(
        t,
        "[[walls]]\nname = \"top\"\npoint = [0.0, 0.0, {top:e}]\nnormal = [0.0, 0.0, -1.0]\nfriction = 0.3"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, t)?;
    Ok(path)
}

/// Grain centres of the image packing are this many equivalent diameters apart: close
/// enough that neighbours overlap, so the image has contacts.
pub const IMAGE_SPACING: f64 = 0.9;

/// Writes `dir/labels.nrrd` and the same image as a 3-D TIFF stack `dir/labels.tif`
/// (without the origin, which TIFF cannot hold): the grains of `p` packed on a cubic grid [`IMAGE_SPACING`]
/// equivalent diameters apart and voxelised at `voxel` (m). A voxel centre inside several
/// grains goes to the one it is deepest in (smallest |x|/r), so overlapping neighbours meet
/// over a face, as touching grains do in a segmented scan. Returns the path and the image.
pub fn write_sand_image(
    dir: &Path,
    p: &SandParams,
    voxel: f64,
) -> std::io::Result<(PathBuf, crate::image::LabelImage)> {
    std::fs::create_dir_all(dir)?;
    let shapes: Vec<GrainShape> = (0..p.grains).map(|i| GrainShape::new(p, i)).collect();
    let per_row = (p.grains as f64).cbrt().ceil() as usize;
    let spacing = IMAGE_SPACING * p.size;
    let centres: Vec<[f64; 3]> = (0..p.grains)
        .map(|i| {
            let (x, y, z) = (
                i % per_row,
                (i / per_row) % per_row,
                i / (per_row * per_row),
            );
            [x, y, z].map(|c| c as f64 * spacing)
        })
        .collect();
    let reach = shapes
        .iter()
        .map(GrainShape::bounding_radius)
        .fold(0.0, f64::max);
    let lo = [0, 1, 2].map(|a| centres.iter().map(|c| c[a]).fold(f64::INFINITY, f64::min) - reach);
    let hi = [0, 1, 2].map(|a| {
        centres
            .iter()
            .map(|c| c[a])
            .fold(f64::NEG_INFINITY, f64::max)
            + reach
    });
    let origin = lo.map(|x| x - voxel);
    let size = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / voxel).ceil() as usize + 3);
    let mut labels = vec![0u32; size[0] * size[1] * size[2]];
    for (g, (shape, c)) in shapes.iter().zip(&centres).enumerate() {
        let r = shape.bounding_radius();
        let first = [0, 1, 2].map(|a| (((c[a] - r - origin[a]) / voxel).floor().max(0.0)) as usize);
        let last = [0, 1, 2]
            .map(|a| ((((c[a] + r - origin[a]) / voxel).ceil()) as usize).min(size[a] - 1));
        for k in first[2]..=last[2] {
            for j in first[1]..=last[1] {
                for i in first[0]..=last[0] {
                    let x = [i, j, k].map(|n| n as f64 * voxel);
                    let local = [0, 1, 2].map(|a| origin[a] + x[a] - c[a]);
                    let ratio = shape.depth_ratio(local);
                    if ratio >= 1.0 {
                        continue;
                    }
                    let v = i + size[0] * (j + size[1] * k);
                    let current = labels[v];
                    let deeper = current == 0 || {
                        let o = current as usize - 1;
                        let other = [0, 1, 2].map(|a| origin[a] + x[a] - centres[o][a]);
                        ratio < shapes[o].depth_ratio(other)
                    };
                    if deeper {
                        labels[v] = g as u32 + 1;
                    }
                }
            }
        }
    }
    let image = crate::image::LabelImage {
        size,
        labels,
        spacing: Some(crate::image::Spacing {
            values: [voxel; 3],
            metres_per_unit: Some(1.0),
        }),
        origin,
    };
    let path = dir.join("labels.nrrd");
    crate::image::nrrd::write_nrrd(&path, &image, [voxel; 3])?;
    crate::image::tiff::write_tiff(&dir.join("labels.tif"), &image, [voxel; 3])?;
    Ok((path, image))
}
