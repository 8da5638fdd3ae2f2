//! A normal map as the shader's surface: within a pixel the normal is interpolated
//! bilinearly between the centres of the pixel and its neighbours on the object (never
//! across a crease or depth edge), so sub-pixel samples see the normal turn as on the
//! sphere; the pixel's coverage weighs its value.

use super::Normals;
use crate::{Grid, Pixel, Surface, Vec3};
use reflectance_core::object::normals::EDGE_ANGLE_DEG;

pub(crate) struct MapSurface<'a> {
    normals: &'a Normals,
    scale: f64,
    /// Neighbours whose normal is turned further than the core's edge angle from the
    /// pixel's own are not interpolated with it.
    cos_edge: f64,
}

impl<'a> MapSurface<'a> {
    pub(crate) fn new(normals: &'a Normals) -> Self {
        MapSurface {
            normals,
            scale: Grid::new(normals.size()).scale,
            cos_edge: f64::from(EDGE_ANGLE_DEG).to_radians().cos(),
        }
    }

    fn vector(&self, row: usize, col: usize) -> Option<Vec3> {
        let n = self.normals.at(row, col)?;
        Some(Vec3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2])))
    }

    /// The interpolated normal at (x, y) of `pixel` (the pixel's own normal if it has one).
    fn interpolated(&self, pixel: &Pixel, x: f64, y: f64) -> Option<Vec3> {
        let own = self.vector(pixel.row, pixel.col)?;
        // Continuous (row, column) coordinates in which pixel centres are integers.
        let u = pixel.col as f64 + (x - pixel.corner.0) / self.scale - 0.5;
        let v = pixel.row as f64 + 1.0 - (y - pixel.corner.1) / self.scale - 0.5;
        let (c0, r0) = (u.floor(), v.floor());
        let (fu, fv) = (u - c0, v - r0);
        let mut sum = Vec3::new(0.0, 0.0, 0.0);
        for (dr, wr) in [(0.0, 1.0 - fv), (1.0, fv)] {
            for (dc, wc) in [(0.0, 1.0 - fu), (1.0, fu)] {
                let (row, col) = (r0 + dr, c0 + dc);
                if row < 0.0 || col < 0.0 {
                    continue;
                }
                let Some(n) = self.vector(row as usize, col as usize) else {
                    continue;
                };
                if n.dot(own) >= self.cos_edge {
                    sum = sum + n * (wr * wc);
                }
            }
        }
        let length = sum.dot(sum).sqrt();
        Some(match length > 1e-12 {
            true => sum * (1.0 / length),
            false => own,
        })
    }
}

impl Surface for MapSurface<'_> {
    fn covers(&self, pixel: &Pixel) -> bool {
        self.normals.coverage(pixel.row, pixel.col) > 0.0
            && self.normals.at(pixel.row, pixel.col).is_some()
    }

    fn normal(&self, pixel: &Pixel, x: f64, y: f64) -> Option<Vec3> {
        self.interpolated(pixel, x, y)
    }

    fn footprint_normal(&self, pixel: &Pixel, x: f64, y: f64) -> Vec3 {
        self.interpolated(pixel, x, y)
            .unwrap_or(Vec3::new(0.0, 0.0, 1.0))
    }

    fn weight(&self, pixel: &Pixel) -> f64 {
        f64::from(self.normals.coverage(pixel.row, pixel.col))
    }
}
