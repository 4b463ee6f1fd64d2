//! Labelled 3-D images (μCT segmentations): one integer label per voxel, 0 = void, every
//! grain a distinct label. `mufe import` turns one into a scene of surface grains
//! (docs/SHAPES.md, "Label images"): [`nrrd`] or [`tiff`] reads the file, [`contour`] extracts one
//! closed surface per label whose shared faces coincide where labels touch, [`decimate`]
//! coarsens the free surfaces to the seeding, [`scene`] writes the grain files and the
//! scene and reports any overlap left between touching grains.

pub mod contour;
pub mod decimate;
pub mod nrrd;
pub mod overlap;
pub mod scene;
pub mod tiff;

/// A labelled voxel grid. Voxel (i, j, k) is centred at `origin + (i, j, k) ⊙ spacing`;
/// `labels` is stored with i fastest (the NRRD order).
#[derive(Debug, Clone, PartialEq)]
pub struct LabelImage {
    pub size: [usize; 3],
    pub labels: Vec<u32>,
    /// Voxel spacing as the header gives it, with its length unit when stated.
    pub spacing: Option<Spacing>,
    /// Centre of voxel (0, 0, 0), in the header's units (0 when absent).
    pub origin: [f64; 3],
}

/// Voxel spacing of a header: values per axis and metres per unit (`None`: no unit given).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spacing {
    pub values: [f64; 3],
    pub metres_per_unit: Option<f64>,
}

impl LabelImage {
    /// Linear index of voxel (i, j, k).
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.size[0] * (j + self.size[1] * k)
    }

    /// The label at signed coordinates; 0 (void) outside the image, so every grain is
    /// closed by the image border.
    pub fn label_at(&self, p: [i64; 3]) -> u32 {
        if (0..3).any(|a| p[a] < 0 || p[a] >= self.size[a] as i64) {
            return 0;
        }
        self.labels[self.index(p[0] as usize, p[1] as usize, p[2] as usize)]
    }

    /// For every label present: (label, voxel count, lowest and highest voxel index per
    /// axis), sorted by label.
    pub fn label_boxes(&self) -> Vec<LabelBox> {
        let mut boxes: std::collections::BTreeMap<u32, LabelBox> = Default::default();
        for k in 0..self.size[2] {
            for j in 0..self.size[1] {
                for i in 0..self.size[0] {
                    let l = self.labels[self.index(i, j, k)];
                    if l == 0 {
                        continue;
                    }
                    let p = [i as i64, j as i64, k as i64];
                    let b = boxes.entry(l).or_insert(LabelBox {
                        label: l,
                        voxels: 0,
                        lo: p,
                        hi: p,
                    });
                    b.voxels += 1;
                    for a in 0..3 {
                        b.lo[a] = b.lo[a].min(p[a]);
                        b.hi[a] = b.hi[a].max(p[a]);
                    }
                }
            }
        }
        boxes.into_values().collect()
    }
}

/// Where one label is in the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LabelBox {
    pub label: u32,
    pub voxels: usize,
    pub lo: [i64; 3],
    pub hi: [i64; 3],
}

impl LabelImage {
    /// For every label, the voxel deepest inside it (6-neighbour erosion depth, up to
    /// [`MAX_DEPTH`]; ties go to the voxel nearest the label's voxel centroid): a point
    /// safely inside the grain's surface, whatever its shape.
    pub fn deepest_voxels(&self) -> std::collections::BTreeMap<u32, [i64; 3]> {
        let n = self.labels.len();
        let mut depth: Vec<u8> = self.labels.iter().map(|&l| u8::from(l != 0)).collect();
        let [nx, ny, nz] = self.size.map(|s| s as i64);
        let neighbours = [
            [1, 0, 0],
            [-1, 0, 0],
            [0, 1, 0],
            [0, -1, 0],
            [0, 0, 1],
            [0, 0, -1],
        ];
        for level in 1..MAX_DEPTH {
            let mut next = depth.clone();
            for k in 0..nz {
                for j in 0..ny {
                    for i in 0..nx {
                        let v = self.index(i as usize, j as usize, k as usize);
                        if depth[v] < level {
                            continue;
                        }
                        let deep = neighbours.iter().all(|d| {
                            let p = [i + d[0], j + d[1], k + d[2]];
                            self.label_at(p) == self.labels[v]
                                && depth[self.index(p[0] as usize, p[1] as usize, p[2] as usize)]
                                    >= level
                        });
                        if deep {
                            next[v] = level + 1;
                        }
                    }
                }
            }
            depth = next;
        }
        let mut sums: std::collections::BTreeMap<u32, ([f64; 3], f64)> = Default::default();
        for v in 0..n {
            let l = self.labels[v];
            if l != 0 {
                let p = self.coordinates(v);
                let e = sums.entry(l).or_insert(([0.0; 3], 0.0));
                (0..3).for_each(|a| e.0[a] += p[a] as f64);
                e.1 += 1.0;
            }
        }
        let mut best: std::collections::BTreeMap<u32, (u8, f64, [i64; 3])> = Default::default();
        for v in 0..n {
            let l = self.labels[v];
            if l == 0 {
                continue;
            }
            let p = self.coordinates(v);
            let (s, count) = sums[&l];
            let d2: f64 = (0..3).map(|a| (p[a] as f64 - s[a] / count).powi(2)).sum();
            let e = best.entry(l).or_insert((depth[v], d2, p));
            if depth[v] > e.0 || (depth[v] == e.0 && d2 < e.1) {
                *e = (depth[v], d2, p);
            }
        }
        best.into_iter().map(|(l, (_, _, p))| (l, p)).collect()
    }

    /// (i, j, k) of linear index `v`.
    pub fn coordinates(&self, v: usize) -> [i64; 3] {
        let (nx, ny) = (self.size[0], self.size[1]);
        [
            (v % nx) as i64,
            ((v / nx) % ny) as i64,
            (v / (nx * ny)) as i64,
        ]
    }
}

/// Deepest erosion level looked for by [`LabelImage::deepest_voxels`].
pub const MAX_DEPTH: u8 = 4;
