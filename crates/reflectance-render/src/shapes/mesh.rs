//! Triangle meshes: the shading normals of their corners (the file's, else area-weighted
//! over the faces around a vertex that meet it within a crease angle), and a z-buffer
//! rasterizer over the sub-pixel samples, in horizontal bands of bounded memory.

use super::{Normals, Pose, ShapeError, facing, mean_normal};
use crate::{Grid, Vec3};

/// How large a mesh file may be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshLimits {
    /// File size (bytes).
    pub bytes: u64,
    /// Vertices.
    pub vertices: usize,
    /// Triangles (after polygons are split into fans).
    pub triangles: usize,
}

impl Default for MeshLimits {
    fn default() -> Self {
        MeshLimits {
            bytes: 256 << 20,
            vertices: 4_000_000,
            triangles: 4_000_000,
        }
    }
}

/// Unit normals, and for each triangle the indices into them of its corners' normals.
pub type CornerNormals = (Vec<[f32; 3]>, Vec<[u32; 3]>);

/// A triangle mesh with a shading normal per corner.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    /// Unit normals the corners refer to.
    normals: Vec<[f32; 3]>,
    /// Per triangle, the index into `normals` of each corner's normal.
    corners: Vec<[u32; 3]>,
}

/// Faces around a vertex whose normals are within this angle of a face's are smoothed
/// with it when the file gives no normals; sharper edges stay creases.
pub const CREASE_DEG: f64 = 40.0;

fn vec3(p: [f64; 3]) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

fn cross(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

impl Mesh {
    /// A mesh from positions, triangles (indices into `positions`) and optionally a unit
    /// normal per vertex and the normal indices of each triangle's corners. Triangles with
    /// an index out of range are refused; without normals they are computed.
    pub fn new(
        positions: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
        normals: Option<CornerNormals>,
    ) -> Result<Mesh, ShapeError> {
        let in_range = |t: &[u32; 3], n: usize| t.iter().all(|&i| (i as usize) < n);
        if !triangles.iter().all(|t| in_range(t, positions.len())) {
            return Err(ShapeError::Parameter(
                "a triangle's vertex is out of range".into(),
            ));
        }
        if !positions.iter().flatten().all(|c| c.is_finite()) {
            return Err(ShapeError::Parameter("a vertex is not finite".into()));
        }
        let (normals, corners) = match normals {
            Some((normals, corners)) => {
                let ok = corners.len() == triangles.len()
                    && corners.iter().all(|c| in_range(c, normals.len()));
                if !ok {
                    return Err(ShapeError::Parameter(
                        "a corner's normal is out of range".into(),
                    ));
                }
                (normals, corners)
            }
            None => crease_normals(&positions, &triangles),
        };
        let mesh = Mesh {
            positions,
            triangles,
            normals,
            corners,
        };
        let (_, radius) = mesh.bounds();
        if !radius.is_finite() {
            return Err(ShapeError::Parameter(
                "the mesh's extent is not finite".into(),
            ));
        }
        match (0..mesh.triangles.len()).any(|t| mesh.area_normal(t).dot(mesh.area_normal(t)) > 0.0)
        {
            true => Ok(mesh),
            false => Err(ShapeError::Empty),
        }
    }

    /// Triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Twice the triangle's area along its normal (right-handed winding).
    fn area_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.triangles[t].map(|i| vec3(self.positions[i as usize]));
        cross(b - a, c - a)
    }

    /// The centre of the bounding box and the largest distance of a vertex from it.
    fn bounds(&self) -> (Vec3, f64) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for t in &self.triangles {
            for &i in t {
                let p = self.positions[i as usize];
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        let centre = Vec3::new(
            0.5 * (lo[0] + hi[0]),
            0.5 * (lo[1] + hi[1]),
            0.5 * (lo[2] + hi[2]),
        );
        let radius = (self.triangles.iter().flatten())
            .map(|&i| {
                let d = vec3(self.positions[i as usize]) - centre;
                d.dot(d).sqrt()
            })
            .fold(0.0, f64::max);
        (centre, radius)
    }
}

/// Per-corner normals: the area-weighted mean of the normals of the faces around the
/// corner's vertex within [`CREASE_DEG`] of the corner's face.
fn crease_normals(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> CornerNormals {
    let faces: Vec<Vec3> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| vec3(positions[i as usize]));
            cross(b - a, c - a)
        })
        .collect();
    let mut around: Vec<Vec<u32>> = vec![Vec::new(); positions.len()];
    for (f, t) in triangles.iter().enumerate() {
        for &v in t {
            around[v as usize].push(f as u32);
        }
    }
    let cos_crease = CREASE_DEG.to_radians().cos();
    let unit = |n: Vec3| {
        let l = n.dot(n).sqrt();
        if l > 0.0 { n * (1.0 / l) } else { n }
    };
    let mut normals = Vec::with_capacity(3 * triangles.len());
    let mut corners = Vec::with_capacity(triangles.len());
    for (f, t) in triangles.iter().enumerate() {
        let own = unit(faces[f]);
        let corner = t.map(|v| {
            let near = around[v as usize].iter().map(|&g| faces[g as usize]);
            let smooth = near
                .filter(|&g| unit(g).dot(own) >= cos_crease)
                .fold(Vec3::new(0.0, 0.0, 0.0), |s, g| s + g);
            let n = unit(smooth);
            normals.push([n.x as f32, n.y as f32, n.z as f32]);
            (normals.len() - 1) as u32
        });
        corners.push(corner);
    }
    (normals, corners)
}

/// A triangle in camera space: sub-sample coordinates (column, row) of its corners, depths
/// and its camera-space corner normals and face normal (facing the camera).
struct Projected {
    xy: [(f64, f64); 3],
    depth: [f64; 3],
    normals: [Vec3; 3],
    face: Vec3,
    /// Twice the signed area in sub-sample coordinates.
    area: f64,
}

/// The sub-sample grid: `side` = size · samples sub-samples a side.
struct SampleGrid {
    side: usize,
    samples: usize,
    grid: Grid,
}

impl SampleGrid {
    /// Camera (x, y) → continuous sub-sample (column, row), sample centres at integers.
    fn to_samples(&self, p: Vec3) -> (f64, f64) {
        let k = self.samples as f64;
        let half = self.side as f64 / (2.0 * k);
        let col = (p.x / self.grid.scale + half) * k - 0.5;
        let row = (half - p.y / self.grid.scale) * k - 0.5;
        (col, row)
    }
}

fn project(
    mesh: &Mesh,
    pose: &Pose,
    fit: (Vec3, f64),
    grid: &SampleGrid,
    t: usize,
) -> Option<Projected> {
    let (centre, radius) = fit;
    let camera = |i: u32| pose.apply(vec3(mesh.positions[i as usize]) - centre) * (1.0 / radius);
    let p = mesh.triangles[t].map(camera);
    let xy = p.map(|q| grid.to_samples(q));
    let area =
        (xy[1].0 - xy[0].0) * (xy[2].1 - xy[0].1) - (xy[2].0 - xy[0].0) * (xy[1].1 - xy[0].1);
    let face = cross(p[1] - p[0], p[2] - p[0]);
    let length = face.dot(face).sqrt();
    if area.abs() < 1e-12 || length == 0.0 {
        return None;
    }
    let face = face * (1.0 / length);
    let face = if face.z < 0.0 { face * -1.0 } else { face };
    let normals = mesh.corners[t].map(|i| {
        let n = mesh.normals[i as usize];
        pose.apply(Vec3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2])))
    });
    Some(Projected {
        xy,
        depth: p.map(|q| q.z),
        normals,
        face,
        area,
    })
}

impl Projected {
    /// Barycentric weights of sub-sample (col, row).
    fn barycentric(&self, col: f64, row: f64) -> [f64; 3] {
        let [a, b, c] = self.xy;
        let edge =
            |p: (f64, f64), q: (f64, f64)| (q.0 - p.0) * (row - p.1) - (col - p.0) * (q.1 - p.1);
        [edge(b, c), edge(c, a), edge(a, b)].map(|e| e / self.area)
    }

    /// Barycentric weights of sub-sample (col, row), if inside (edges included).
    fn weights(&self, col: f64, row: f64) -> Option<[f64; 3]> {
        let w = self.barycentric(col, row);
        w.iter().all(|&v| v >= 0.0).then_some(w)
    }

    fn depth(&self, w: [f64; 3]) -> f64 {
        w[0] * self.depth[0] + w[1] * self.depth[1] + w[2] * self.depth[2]
    }

    /// The shading normal at weights `w`, turned to the face's side, facing the camera.
    fn normal(&self, w: [f64; 3]) -> Vec3 {
        let n = self.normals[0] * w[0] + self.normals[1] * w[1] + self.normals[2] * w[2];
        let n = if n.dot(self.face) < 0.0 { n * -1.0 } else { n };
        match n.dot(n) > 1e-24 {
            true => facing(n.normalized()).unwrap_or(self.face),
            false => self.face,
        }
    }

    /// Sub-sample rows and columns of its bounding box within the grid.
    fn bounds(&self, side: usize) -> Option<([usize; 2], [usize; 2])> {
        let range = |values: [f64; 3]| {
            let lo = values
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min)
                .ceil()
                .max(0.0);
            let hi = values
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max)
                .floor();
            (hi >= lo && lo < side as f64).then(|| [lo as usize, (hi as usize).min(side - 1)])
        };
        Some((range(self.xy.map(|p| p.0))?, range(self.xy.map(|p| p.1))?))
    }
}

/// Sub-samples a band holds at most.
const BAND_SAMPLES: usize = 1 << 21;

/// Rasterize `mesh` in `pose`, fitted to the unit sphere, with `samples`² sub-samples a pixel.
pub(crate) fn rasterize(mesh: &Mesh, pose: &Pose, size: usize, samples: usize) -> Normals {
    let grid = SampleGrid {
        side: size * samples,
        samples,
        grid: Grid::new(size),
    };
    let (centre, radius) = mesh.bounds();
    let fit = (centre, radius);
    let projected: Vec<Projected> = (0..mesh.triangles.len())
        .filter_map(|t| project(mesh, pose, fit, &grid, t))
        .collect();
    let rows_per_band = (BAND_SAMPLES / grid.side.max(1)).max(1).div_ceil(samples) * samples;
    let mut bands: Vec<Vec<u32>> = vec![Vec::new(); grid.side.div_ceil(rows_per_band)];
    for (i, tri) in projected.iter().enumerate() {
        if let Some((_, [top, bottom])) = tri.bounds(grid.side) {
            let span = top / rows_per_band..=bottom / rows_per_band;
            for band in &mut bands[span] {
                band.push(i as u32);
            }
        }
    }
    let mut out = Normals {
        size,
        normals: vec![[0.0; 3]; size * size],
        coverage: vec![0.0; size * size],
    };
    for (b, members) in bands.iter().enumerate() {
        let rows = b * rows_per_band..((b + 1) * rows_per_band).min(grid.side);
        let hits = zbuffer(&projected, members, &grid, rows.clone());
        resolve(&projected, &hits, &grid, rows, &mut out);
    }
    out
}

/// No triangle at a sub-sample.
const NONE: u32 = u32::MAX;

/// The nearest triangle (index, or [`NONE`], and depth) at each sub-sample of rows `rows`.
fn zbuffer(
    projected: &[Projected],
    members: &[u32],
    grid: &SampleGrid,
    rows: std::ops::Range<usize>,
) -> Vec<(u32, f64)> {
    let mut hits = vec![(NONE, f64::NEG_INFINITY); rows.len() * grid.side];
    for &i in members {
        let tri = &projected[i as usize];
        let Some(([left, right], [top, bottom])) = tri.bounds(grid.side) else {
            continue;
        };
        for row in top.max(rows.start)..=bottom.min(rows.end - 1) {
            for col in left..=right {
                let Some(w) = tri.weights(col as f64, row as f64) else {
                    continue;
                };
                let depth = tri.depth(w);
                let cell = &mut hits[(row - rows.start) * grid.side + col];
                if cell.0 == NONE || depth > cell.1 {
                    *cell = (i, depth);
                }
            }
        }
    }
    hits
}

/// Each pixel of the band: the normalized mean of its sub-samples' normals and coverage.
fn resolve(
    projected: &[Projected],
    hits: &[(u32, f64)],
    grid: &SampleGrid,
    rows: std::ops::Range<usize>,
    out: &mut Normals,
) {
    let (k, size) = (grid.samples, out.size);
    for row in rows.start / k..rows.end / k {
        for col in 0..size {
            let samples = (0..k * k).filter_map(|s| {
                let (sub_row, sub_col) = (row * k + s / k, col * k + s % k);
                let (i, _) = hits[(sub_row - rows.start) * grid.side + sub_col];
                let tri = projected.get(i as usize)?;
                Some(tri.normal(tri.barycentric(sub_col as f64, sub_row as f64)))
            });
            let (n, count) = mean_normal(samples);
            out.normals[row * size + col] = n;
            out.coverage[row * size + col] = (count as f64 / (k * k) as f64) as f32;
        }
    }
}
