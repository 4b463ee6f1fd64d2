//! NRRD label images (teem's "nearly raw raster data": a text header of `field: value`
//! lines, a blank line, then the voxels).
//!
//! Read: dimension 3, integer types (8 to 64 bits, signed or not; labels must be ≥ 0 and
//! fit in 32 bits), `raw` or `ascii`/`text` encoding, either endianness, data attached or in
//! a detached `data file`, `byte skip` (−1: the data end the file); voxel spacing from
//! `spacings` or an axis-aligned `space directions`, its unit from `space units`, the first
//! voxel's centre from `space origin`. Compressed encodings (gzip, bzip2) are refused with
//! the field named: re-save the image raw. Written: uint16 or uint32, raw, little-endian,
//! spacing and origin in metres.

use std::path::Path;

use super::{LabelImage, Spacing};
use crate::error::{echo, InputError};

/// Most voxels read (4 GiB of u32 labels).
const MAX_VOXELS: usize = 1 << 30;

/// Reads a label image; every problem is an input error naming the file and header field.
pub fn read_nrrd(path: &Path) -> Result<LabelImage, InputError> {
    let file = path.display().to_string();
    let bad = |field: &str, message: String| InputError::new(&file, field, message);
    let bytes = std::fs::read(path).map_err(|e| bad("file", format!("cannot read: {e}")))?;
    let (fields, data_start) = parse_header(&bytes).map_err(|(f, m)| bad(&f, m))?;
    let get = |name: &str| {
        fields
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    };
    let need = |name: &str| get(name).ok_or_else(|| bad(name, "missing from the header".into()));

    let dimension = need("dimension")?;
    if dimension.trim() != "3" {
        return Err(bad(
            "dimension",
            format!("must be 3 for a label volume, got '{}'", echo(dimension)),
        ));
    }
    let sizes = numbers::<usize>(need("sizes")?, 3).ok_or_else(|| {
        bad(
            "sizes",
            format!(
                "expected 3 positive integers, got '{}'",
                echo(need("sizes").unwrap_or(""))
            ),
        )
    })?;
    let size = [sizes[0], sizes[1], sizes[2]];
    let voxels = size
        .iter()
        .try_fold(1usize, |n, &s| n.checked_mul(s))
        .filter(|&n| n > 0 && n <= MAX_VOXELS)
        .ok_or_else(|| {
            bad(
                "sizes",
                format!("{size:?} is empty or has more than {MAX_VOXELS} voxels"),
            )
        })?;
    let kind = voxel_type(need("type")?).ok_or_else(|| {
        bad(
            "type",
            format!(
                "'{}' is not an integer type; labels must be integers (uint8 … int64)",
                echo(get("type").unwrap_or(""))
            ),
        )
    })?;
    let encoding = need("encoding")?.trim().to_ascii_lowercase();
    let little = match get("endian").map(|e| e.trim().to_ascii_lowercase()) {
        Some(e) if e == "little" => true,
        Some(e) if e == "big" => false,
        None if kind.bytes == 1 || encoding != "raw" => true,
        None => {
            return Err(bad(
                "endian",
                "missing; required for multi-byte raw data".into(),
            ))
        }
        Some(e) => {
            return Err(bad(
                "endian",
                format!("'{}' is not little or big", echo(&e)),
            ))
        }
    };

    let data: Vec<u8> = match get("data file").or_else(|| get("datafile")) {
        Some(name) => {
            let name = name.trim();
            if name.starts_with("LIST") || name.contains('%') || name.contains(' ') {
                return Err(bad(
                    "data file",
                    format!("'{}': only a single detached file is supported", echo(name)),
                ));
            }
            let detached = path.parent().unwrap_or(Path::new(".")).join(name);
            std::fs::read(&detached).map_err(|e| {
                bad(
                    "data file",
                    format!("cannot read '{}': {e}", detached.display()),
                )
            })?
        }
        None => bytes[data_start..].to_vec(),
    };
    let labels = match encoding.as_str() {
        "raw" => {
            let expected = voxels * kind.bytes;
            let skip = get("byte skip").map_or(Ok(0i64), |s| {
                s.trim()
                    .parse::<i64>()
                    .map_err(|_| bad("byte skip", format!("'{}' is not an integer", echo(s))))
            })?;
            let start = if skip == -1 {
                data.len().checked_sub(expected)
            } else if skip >= 0 {
                Some(skip as usize)
            } else {
                None
            };
            let raw = start
                .and_then(|s| data.get(s..s + expected))
                .ok_or_else(|| {
                    bad(
                        "sizes",
                        format!(
                            "{size:?} of {} bytes need {expected} bytes of data, the file has {}",
                            kind.bytes,
                            data.len()
                        ),
                    )
                })?;
            raw.chunks_exact(kind.bytes)
                .enumerate()
                .map(|(n, c)| kind.decode(c, little).ok_or(n))
                .collect::<Result<Vec<u32>, usize>>()
                .map_err(|n| bad("data", format!("voxel {n} is not a label in 0 … 2^32−1")))?
        }
        "ascii" | "text" | "txt" => {
            let text = std::str::from_utf8(&data)
                .map_err(|_| bad("data", "ascii data is not text".into()))?;
            let labels: Vec<u32> = text
                .split_whitespace()
                .enumerate()
                .map(|(n, w)| w.parse::<u32>().map_err(|_| (n, w)))
                .collect::<Result<_, _>>()
                .map_err(|(n, w)| {
                    bad(
                        "data",
                        format!("voxel {n}: '{}' is not a label ≥ 0", echo(w)),
                    )
                })?;
            if labels.len() != voxels {
                return Err(bad(
                    "sizes",
                    format!(
                        "{size:?} need {voxels} values, the data have {}",
                        labels.len()
                    ),
                ));
            }
            labels
        }
        other => {
            return Err(bad(
                "encoding",
                format!(
                    "'{}' is not supported; re-save the image with raw encoding",
                    echo(other)
                ),
            ))
        }
    };

    let metres_per_unit = match get("space units") {
        Some(u) => {
            let units: Vec<&str> = u
                .split('"')
                .map(str::trim)
                .filter(|s| !s.is_empty())
                .collect();
            let factors: Option<Vec<f64>> = units.iter().map(|u| unit_factor(u)).collect();
            match factors {
                Some(f) if f.len() == 3 && f.iter().all(|&x| x == f[0]) => Some(f[0]),
                _ => {
                    return Err(bad(
                        "space units",
                        format!(
                            "'{}': expected three equal units of m, cm, mm, um or microns",
                            echo(u)
                        ),
                    ))
                }
            }
        }
        None => None,
    };
    let spacing_values = if let Some(s) = get("spacings") {
        Some(
            numbers::<f64>(s, 3)
                .filter(|v| v.iter().all(|x| x.is_finite() && *x > 0.0))
                .ok_or_else(|| {
                    bad(
                        "spacings",
                        format!("expected 3 numbers > 0, got '{}'", echo(s)),
                    )
                })?,
        )
    } else if let Some(s) = get("space directions") {
        Some(axis_aligned_directions(s).ok_or_else(|| {
            bad(
                "space directions",
                format!(
                    "'{}': expected three axis-aligned vectors (a,0,0) (0,b,0) (0,0,c); oblique grids are not supported",
                    echo(s)
                ),
            )
        })?)
    } else {
        None
    };
    let spacing = spacing_values.map(|v| Spacing {
        values: [v[0], v[1], v[2]],
        metres_per_unit,
    });
    let origin = match get("space origin") {
        Some(s) => vector(s)
            .filter(|v| v.len() == 3 && v.iter().all(|x| x.is_finite()))
            .map(|v| [v[0], v[1], v[2]])
            .ok_or_else(|| {
                bad(
                    "space origin",
                    format!("expected (x,y,z), got '{}'", echo(s)),
                )
            })?,
        None => [0.0; 3],
    };
    Ok(LabelImage {
        size,
        labels,
        spacing,
        origin,
    })
}

/// Writes `image` as uint16 (labels < 65536) or uint32, raw little-endian, with spacing
/// and origin given in metres.
pub fn write_nrrd(path: &Path, image: &LabelImage, spacing_m: [f64; 3]) -> std::io::Result<()> {
    use std::io::Write as _;
    let wide = image.labels.iter().any(|&l| l > u16::MAX as u32);
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    let [sx, sy, sz] = spacing_m;
    let o = image.origin;
    write!(
        out,
        "NRRD0004\n# label image written by mufe: 0 = void, one label per grain\ntype: {}\ndimension: 3\nspace dimension: 3\nsizes: {} {} {}\nspace directions: ({sx:e},0,0) (0,{sy:e},0) (0,0,{sz:e})\nspace units: \"m\" \"m\" \"m\"\nspace origin: ({:e},{:e},{:e})\nencoding: raw\nendian: little\n\n",
        if wide { "uint32" } else { "uint16" },
        image.size[0],
        image.size[1],
        image.size[2],
        o[0],
        o[1],
        o[2]
    )?;
    for &l in &image.labels {
        if wide {
            out.write_all(&l.to_le_bytes())?;
        } else {
            out.write_all(&(l as u16).to_le_bytes())?;
        }
    }
    out.flush()
}

/// Header fields (lower-case names) and where the attached data start.
type Header = (Vec<(String, String)>, usize);

fn parse_header(bytes: &[u8]) -> Result<Header, (String, String)> {
    if !bytes.starts_with(b"NRRD") {
        return Err((
            "magic".into(),
            "not an NRRD file (it must start with 'NRRD000x')".into(),
        ));
    }
    let mut fields = Vec::new();
    let mut pos = 0;
    let mut first = true;
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err((
                "header".into(),
                "ends before the blank line that ends it".into(),
            ));
        };
        let line = std::str::from_utf8(&bytes[pos..pos + len])
            .map_err(|_| ("header".to_string(), "is not text".to_string()))?
            .trim_end_matches('\r');
        pos += len + 1;
        if first {
            first = false;
            continue;
        }
        if line.is_empty() {
            return Ok((fields, pos));
        }
        if line.starts_with('#') {
            continue;
        }
        // Key/value pairs (`key:=value`) carry no geometry; fields are `name: value`.
        if line.contains(":=") {
            continue;
        }
        let Some((k, v)) = line.split_once(": ") else {
            return Err((
                "header".into(),
                format!("line '{}' is not 'field: value'", echo(line)),
            ));
        };
        fields.push((k.trim().to_ascii_lowercase(), v.trim().to_string()));
        if pos >= bytes.len() {
            // A detached header may end without the blank line.
            return Ok((fields, pos));
        }
    }
}

fn numbers<T: std::str::FromStr>(s: &str, n: usize) -> Option<Vec<T>> {
    let v: Vec<T> = s
        .split_whitespace()
        .map(|w| w.parse().ok())
        .collect::<Option<_>>()?;
    (v.len() == n).then_some(v)
}

/// "(a,b,c)" → [a, b, c].
fn vector(s: &str) -> Option<Vec<f64>> {
    let inner = s.trim().strip_prefix('(')?.strip_suffix(')')?;
    inner.split(',').map(|w| w.trim().parse().ok()).collect()
}

/// "(a,0,0) (0,b,0) (0,0,c)" → [a, b, c] (magnitudes), or `None` when not axis-aligned.
fn axis_aligned_directions(s: &str) -> Option<Vec<f64>> {
    let vectors: Vec<Vec<f64>> = s.split_whitespace().map(vector).collect::<Option<_>>()?;
    if vectors.len() != 3 {
        return None;
    }
    let mut out = Vec::with_capacity(3);
    for (axis, v) in vectors.iter().enumerate() {
        if v.len() != 3 || (0..3).any(|k| k != axis && v[k] != 0.0) {
            return None;
        }
        let a = v[axis].abs();
        if !(a.is_finite() && a > 0.0) {
            return None;
        }
        out.push(a);
    }
    Some(out)
}

/// Metres per unit of a `space units` entry.
fn unit_factor(u: &str) -> Option<f64> {
    match u.to_ascii_lowercase().as_str() {
        "m" | "meter" | "meters" | "metre" | "metres" => Some(1.0),
        "cm" => Some(1e-2),
        "mm" => Some(1e-3),
        "um" | "µm" | "μm" | "micron" | "microns" => Some(1e-6),
        _ => None,
    }
}

#[derive(Debug, Clone, Copy)]
struct VoxelType {
    bytes: usize,
    signed: bool,
}

impl VoxelType {
    fn decode(&self, c: &[u8], little: bool) -> Option<u32> {
        let mut b = [0u8; 8];
        if little {
            b[..c.len()].copy_from_slice(c);
        } else {
            for (k, &x) in c.iter().rev().enumerate() {
                b[k] = x;
            }
        }
        let unsigned = u64::from_le_bytes(b);
        let value: i128 = if self.signed {
            let shift = 64 - 8 * self.bytes as u32;
            (((unsigned << shift) as i64) >> shift) as i128
        } else {
            unsigned as i128
        };
        u32::try_from(value).ok()
    }
}

fn voxel_type(t: &str) -> Option<VoxelType> {
    let t = t.trim().to_ascii_lowercase();
    let (bytes, signed) = match t.as_str() {
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => (1, false),
        "signed char" | "int8" | "int8_t" => (1, true),
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => (2, false),
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            (2, true)
        }
        "uint" | "unsigned int" | "uint32" | "uint32_t" => (4, false),
        "int" | "signed int" | "int32" | "int32_t" => (4, true),
        "ulonglong" | "unsigned long long" | "unsigned long long int" | "uint64" | "uint64_t" => {
            (8, false)
        }
        "longlong"
        | "long long"
        | "long long int"
        | "signed long long"
        | "signed long long int"
        | "int64"
        | "int64_t" => (8, true),
        _ => return None,
    };
    Some(VoxelType { bytes, signed })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::TestDir;

    fn image() -> LabelImage {
        LabelImage {
            size: [3, 2, 2],
            labels: (0..12).map(|i| (i % 4) as u32).collect(),
            spacing: None,
            origin: [1e-3, 0.0, -2e-3],
        }
    }

    #[test]
    fn written_images_read_back_with_spacing_in_metres() {
        let dir = TestDir::new("nrrd_written");
        let p = dir.join("a.nrrd");
        write_nrrd(&p, &image(), [1e-5, 2e-5, 3e-5]).unwrap();
        let r = read_nrrd(&p).unwrap();
        assert_eq!(r.labels, image().labels);
        assert_eq!(r.size, [3, 2, 2]);
        assert_eq!(r.origin, [1e-3, 0.0, -2e-3]);
        let s = r.spacing.unwrap();
        assert_eq!(s.values, [1e-5, 2e-5, 3e-5]);
        assert_eq!(s.metres_per_unit, Some(1.0));
    }

    #[test]
    fn big_endian_signed_ascii_and_detached_data_are_read() {
        let dir = TestDir::new("nrrd_detached");
        let p = dir.join("b.nrrd");
        let mut bytes =
            b"NRRD0004\ntype: short\ndimension: 3\nsizes: 2 1 1\nspacings: 5 5 5\nencoding: raw\nendian: big\n\n"
                .to_vec();
        bytes.extend([0x01, 0x02, 0x00, 0x07]);
        std::fs::write(&p, &bytes).unwrap();
        let r = read_nrrd(&p).unwrap();
        assert_eq!(r.labels, vec![0x0102, 7]);
        assert_eq!(r.spacing.unwrap().metres_per_unit, None);

        std::fs::write(
            &p,
            "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 1\nspace units: \"mm\" \"mm\" \"mm\"\nspacings: 0.01 0.01 0.01\nencoding: ascii\n\n0 1\n2 0\n",
        )
        .unwrap();
        let r = read_nrrd(&p).unwrap();
        assert_eq!(r.labels, vec![0, 1, 2, 0]);
        assert_eq!(r.spacing.unwrap().metres_per_unit, Some(1e-3));

        let raw = dir.join("c.raw");
        std::fs::write(&raw, [4u8, 0, 4, 0]).unwrap();
        std::fs::write(
            &p,
            "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 1\nencoding: raw\ndata file: c.raw\n",
        )
        .unwrap();
        assert_eq!(read_nrrd(&p).unwrap().labels, vec![4, 0, 4, 0]);
    }

    #[test]
    fn every_bad_header_names_its_field() {
        let dir = TestDir::new("nrrd_bad_header");
        let p = dir.join("d.nrrd");
        let head = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 1 1\nencoding: raw\n";
        let cases = [
            (
                "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 1\nencoding: raw\n\n\0\0",
                "type",
            ),
            (
                "NRRD0004\ntype: uint8\ndimension: 2\nsizes: 2 1\nencoding: raw\n\n\0\0",
                "dimension",
            ),
            (
                "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 1 1\nencoding: gzip\n\n\0\0",
                "encoding",
            ),
            (
                "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 x 1\nencoding: raw\n\n\0\0",
                "sizes",
            ),
            (
                "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 1 1\nencoding: raw\n\n\0",
                "sizes",
            ),
            (
                "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 2 1 1\nencoding: raw\n\n\0\0\0\0",
                "endian",
            ),
            (
                "NRRD0004\ntype: int8\ndimension: 3\nsizes: 2 1 1\nencoding: raw\n\n\0\u{ff}",
                "data",
            ),
            ("P5 2 1 255\n\0\0", "magic"),
        ];
        for (text, field) in cases {
            std::fs::write(&p, text).unwrap();
            let e = read_nrrd(&p).unwrap_err();
            assert_eq!(e.item, field, "{text:?}: {e}");
            assert!(!e.to_string().contains('\n'));
        }
        for (extra, field) in [
            (
                "space directions: (1,1,0) (0,1,0) (0,0,1)\n",
                "space directions",
            ),
            (
                "space units: \"mm\" \"mm\" \"inch\"\nspacings: 1 1 1\n",
                "space units",
            ),
            ("spacings: 1 0 1\n", "spacings"),
            ("space origin: (1,2)\n", "space origin"),
        ] {
            std::fs::write(&p, format!("{head}{extra}\n\0\0")).unwrap();
            assert_eq!(read_nrrd(&p).unwrap_err().item, field, "{extra}");
        }
    }
}
