//! Multi-page (3-D) TIFF label images, read with the `tiff` crate (image-rs; pure Rust,
//! the decoder behind the `image` crate): one grayscale page per z slice, x along a row.
//!
//! Read: every page single-sample grayscale of the same width and height, integer samples
//! (8 to 64 bits, signed or not; labels must be ≥ 0 and fit in 32 bits), uncompressed,
//! LZW or Deflate. Voxel spacing from the ImageJ convention, which is what Fiji, Avizo and
//! most segmentation tools write for stacks: `XResolution`/`YResolution` in pixels per
//! unit, and `unit=` and `spacing=` (the z step) in the `ImageDescription`. Without a z
//! spacing or a known unit the spacing is left to `--voxel-size` (a plain TIFF's 72 dpi
//! is a screen setting, not a voxel size). Written: uint16 or uint32 pages with the ImageJ
//! description, unit micron.

use std::path::Path;

use tiff::decoder::{ifd::Value, Decoder, DecodingResult, Limits};
use tiff::encoder::{colortype, Rational, TiffEncoder};
use tiff::tags::{ResolutionUnit, Tag};
use tiff::ColorType;

use super::{LabelImage, Spacing};
use crate::error::{echo, InputError};

/// Most voxels read (as for NRRD: 4 GiB of u32 labels).
const MAX_VOXELS: usize = 1 << 30;

/// Reads a 3-D label stack; every problem is an input error naming the file and the tag or
/// page.
pub fn read_tiff(path: &Path) -> Result<LabelImage, InputError> {
    let file = path.display().to_string();
    let bad = |field: &str, message: String| InputError::new(&file, field, message);
    let reader = std::fs::File::open(path)
        .map(std::io::BufReader::new)
        .map_err(|e| bad("file", format!("cannot read: {e}")))?;
    let mut decoder = Decoder::new(reader)
        .map_err(|e| bad("header", format!("not a readable TIFF: {e}")))?
        .with_limits(Limits::unlimited());
    let tiff_err = |page: usize, e: tiff::TiffError| bad(&format!("page {page}"), e.to_string());
    let (width, height) = decoder.dimensions().map_err(|e| tiff_err(0, e))?;
    let (width, height) = (width as usize, height as usize);
    let description = decoder
        .get_tag_ascii_string(Tag::ImageDescription)
        .unwrap_or_default();
    let spacing = spacing_of_first_page(&mut decoder, &description);

    let mut labels: Vec<u32> = Vec::new();
    let mut page = 0usize;
    loop {
        match decoder.colortype().map_err(|e| tiff_err(page, e))? {
            ColorType::Gray(_) => {}
            other => {
                return Err(bad(
                    &format!("page {page}"),
                    format!("is {other:?}; a label image has one integer sample per voxel"),
                ))
            }
        }
        let dims = decoder.dimensions().map_err(|e| tiff_err(page, e))?;
        if (dims.0 as usize, dims.1 as usize) != (width, height) {
            return Err(bad(
                &format!("page {page}"),
                format!(
                    "is {}×{} pixels, page 0 is {width}×{height}; every slice must match",
                    dims.0, dims.1
                ),
            ));
        }
        if labels.len() + width * height > MAX_VOXELS {
            return Err(bad(
                &format!("page {page}"),
                format!("the stack has more than {MAX_VOXELS} voxels"),
            ));
        }
        let data = decoder.read_image().map_err(|e| tiff_err(page, e))?;
        append_labels(&mut labels, data).map_err(|why| bad(&format!("page {page}"), why))?;
        page += 1;
        if !decoder.more_images() {
            break;
        }
        decoder.next_image().map_err(|e| tiff_err(page, e))?;
    }
    Ok(LabelImage {
        size: [width, height, page],
        labels,
        spacing,
        origin: [0.0; 3],
    })
}

/// Converts one decoded page to labels, refusing floats and negative or > 32-bit values.
fn append_labels(out: &mut Vec<u32>, data: DecodingResult) -> Result<(), String> {
    fn checked<T: Copy + TryInto<u32> + std::fmt::Display>(
        out: &mut Vec<u32>,
        v: &[T],
    ) -> Result<(), String> {
        for &x in v {
            out.push(x.try_into().map_err(|_| {
                format!("holds label {x}; labels must be 0 … {} integers", u32::MAX)
            })?);
        }
        Ok(())
    }
    match data {
        DecodingResult::U8(v) => checked(out, &v),
        DecodingResult::U16(v) => checked(out, &v),
        DecodingResult::U32(v) => checked(out, &v),
        DecodingResult::U64(v) => checked(out, &v),
        DecodingResult::I8(v) => checked(out, &v),
        DecodingResult::I16(v) => checked(out, &v),
        DecodingResult::I32(v) => checked(out, &v),
        DecodingResult::I64(v) => checked(out, &v),
        _ => Err("holds floating-point samples; labels must be integers".into()),
    }
}

/// The ImageJ spacing: x and y from the resolution tags, z from `spacing=`, all in `unit=`.
fn spacing_of_first_page<R: std::io::Read + std::io::Seek>(
    decoder: &mut Decoder<R>,
    description: &str,
) -> Option<Spacing> {
    let field = |key: &str| {
        description.lines().find_map(|l| {
            l.trim()
                .strip_prefix(key)
                .and_then(|rest| rest.strip_prefix('='))
                .map(str::trim)
        })
    };
    let z: f64 = field("spacing")?.parse().ok()?;
    let metres_per_unit = match field("unit").unwrap_or("") {
        "micron" | "um" | "µm" | "μm" | "\\u00B5m" => Some(1e-6),
        "nm" | "nanometer" => Some(1e-9),
        "mm" | "millimeter" => Some(1e-3),
        "cm" | "centimeter" => Some(1e-2),
        "m" | "meter" => Some(1.0),
        "inch" => Some(0.0254),
        _ => None,
    };
    let mut per_unit = |tag| match decoder.find_tag(tag).ok()?? {
        Value::Rational(n, d) if n > 0 && d > 0 => Some(d as f64 / n as f64),
        _ => None,
    };
    let (x, y) = (per_unit(Tag::XResolution)?, per_unit(Tag::YResolution)?);
    [x, y, z]
        .iter()
        .all(|v| v.is_finite() && *v > 0.0)
        .then_some(Spacing {
            values: [x, y, z],
            metres_per_unit,
        })
}

/// Writes `image` as a stack of uint16 (labels < 65536) or uint32 pages with the ImageJ
/// spacing in micrometres; the origin is not stored (TIFF has no field for it).
pub fn write_tiff(path: &Path, image: &LabelImage, spacing_m: [f64; 3]) -> std::io::Result<()> {
    let to_io = |e: tiff::TiffError| std::io::Error::other(e.to_string());
    let [nx, ny, nz] = image.size;
    let wide = image.labels.iter().any(|&l| l > u16::MAX as u32);
    let um = spacing_m.map(|s| s * 1e6);
    // Pixels per micron as a rational with 9 significant digits.
    let per_um = |s: f64| {
        let denominator = 1_000_000u32;
        Rational {
            n: (denominator as f64 / s).round().max(1.0) as u32,
            d: denominator,
        }
    };
    let description = format!(
        "ImageJ=1.54f\nimages={nz}\nslices={nz}\nunit=micron\nspacing={:e}\nloop=false\nmufe=label image: 0 = void, one label per grain\n",
        um[2]
    );
    let out = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut encoder = TiffEncoder::new(out).map_err(to_io)?;
    for k in 0..nz {
        let slice = &image.labels[k * nx * ny..(k + 1) * nx * ny];
        macro_rules! page {
            ($colour:ty, $data:expr) => {{
                let mut page = encoder
                    .new_image::<$colour>(nx as u32, ny as u32)
                    .map_err(to_io)?;
                page.resolution_unit(ResolutionUnit::None);
                page.x_resolution(per_um(um[0]));
                page.y_resolution(per_um(um[1]));
                page.encoder()
                    .write_tag(Tag::ImageDescription, description.as_str())
                    .map_err(to_io)?;
                page.write_data($data).map_err(to_io)?;
            }};
        }
        if wide {
            page!(colortype::Gray32, slice);
        } else {
            let narrow: Vec<u16> = slice.iter().map(|&l| l as u16).collect();
            page!(colortype::Gray16, &narrow);
        }
    }
    Ok(())
}

/// Reads a label image by its extension: `.tif`/`.tiff` here, anything else as NRRD.
pub fn read_label_image(path: &Path) -> Result<LabelImage, InputError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("tif" | "tiff") => read_tiff(path),
        Some("nrrd" | "nhdr") | None => super::nrrd::read_nrrd(path),
        Some(other) => Err(InputError::new(
            path.display().to_string(),
            "file",
            format!(
                "'.{}' is not a label image format; use .nrrd, .nhdr, .tif or .tiff",
                echo(other)
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stack() -> LabelImage {
        let size = [5, 4, 3];
        let labels = (0..60u32).map(|i| (i * 7) % 5).collect();
        LabelImage {
            size,
            labels,
            spacing: None,
            origin: [0.0; 3],
        }
    }

    #[test]
    fn a_written_stack_reads_back_with_its_labels_and_spacing() {
        let dir = std::env::temp_dir().join(format!("mufe_tiff_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for big in [false, true] {
            let mut image = stack();
            if big {
                image.labels[7] = 70_000;
            }
            let path = dir.join(format!("s{big}.tif"));
            write_tiff(&path, &image, [2.5e-6, 2.5e-6, 4e-6]).unwrap();
            let back = read_label_image(&path).unwrap();
            assert_eq!(back.size, image.size);
            assert_eq!(back.labels, image.labels);
            let s = back.spacing.expect("ImageJ spacing");
            let metres = s.values.map(|v| v * s.metres_per_unit.unwrap());
            for (got, want) in metres.iter().zip([2.5e-6, 2.5e-6, 4e-6]) {
                assert!((got / want - 1.0).abs() < 1e-6, "{got} vs {want}");
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn colour_pages_and_mismatched_slices_are_refused_with_the_page() {
        let dir = std::env::temp_dir().join(format!("mufe_tiff_bad_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rgb = dir.join("rgb.tif");
        {
            let f = std::fs::File::create(&rgb).unwrap();
            let mut e = TiffEncoder::new(f).unwrap();
            e.write_image::<colortype::Gray8>(2, 2, &[0, 1, 1, 0])
                .unwrap();
            e.write_image::<colortype::RGB8>(2, 2, &[0; 12]).unwrap();
        }
        let err = read_tiff(&rgb).unwrap_err().to_string();
        assert!(err.contains("page 1") && err.contains("RGB"), "{err}");
        let sizes = dir.join("sizes.tif");
        {
            let f = std::fs::File::create(&sizes).unwrap();
            let mut e = TiffEncoder::new(f).unwrap();
            e.write_image::<colortype::Gray8>(2, 2, &[0, 1, 1, 0])
                .unwrap();
            e.write_image::<colortype::Gray8>(3, 1, &[0, 1, 1]).unwrap();
        }
        let err = read_tiff(&sizes).unwrap_err().to_string();
        assert!(err.contains("page 1") && err.contains("3×1"), "{err}");
        let float = dir.join("float.tif");
        {
            let f = std::fs::File::create(&float).unwrap();
            let mut e = TiffEncoder::new(f).unwrap();
            e.write_image::<colortype::Gray32Float>(1, 1, &[1.5])
                .unwrap();
        }
        let err = read_tiff(&float).unwrap_err().to_string();
        assert!(err.contains("page 0") && err.contains("floating"), "{err}");
        let odd = dir.join("labels.png");
        std::fs::write(&odd, b"x").unwrap();
        assert!(read_label_image(&odd)
            .unwrap_err()
            .to_string()
            .contains(".png"));
        std::fs::remove_dir_all(&dir).ok();
    }
}
