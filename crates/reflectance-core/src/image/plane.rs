//! A plane of linear luminance as location reads it: an array, or a photograph's 8-bit
//! samples turned into luminance where they are read ([`crate::decode::EncodedPlane`]), so
//! that a phone photograph is searched without a 64-bit plane of all its pixels.

use super::resample;
use crate::util::parallel;
use ndarray::{Array2, ArrayView2};
use std::borrow::Cow;
use std::ops::Range;

/// Linear luminance, `size()` = (height, width), read pixel by pixel or by part.
pub trait Plane: Copy + Send + Sync {
    /// Height and width (px).
    fn size(self) -> (usize, usize);
    /// The luminance of pixel (`y`, `x`), inside the plane.
    fn value(self, y: usize, x: usize) -> f64;
    /// The columns `x0..x0 + line.len()` of row `y`, into `line`.
    fn fill_line(self, y: usize, x0: usize, line: &mut [f64]);

    /// Rows `rows` × columns `cols`, reduced by area by `factor` < 1 (to the bits of
    /// [`resample::downsample`] of that part), or as they are.
    fn part(self, rows: Range<usize>, cols: Range<usize>, factor: f64) -> Array2<f64> {
        let (h, w) = (rows.len(), cols.len());
        let line = |y: usize| {
            let mut line = vec![0.0; w];
            self.fill_line(y, cols.start, &mut line);
            Cow::Owned(line)
        };
        match factor < 1.0 {
            true => {
                let parts = parallel::parts_for(h * w);
                let line = |y: usize| line(rows.start + y);
                resample::downsample_lines_in_parts(line, (h, w), factor, parts)
            }
            false => {
                let values = rows.flat_map(|y| line(y).into_owned()).collect();
                Array2::from_shape_vec((h, w), values).expect("h × w values")
            }
        }
    }
}

impl Plane for ArrayView2<'_, f64> {
    fn size(self) -> (usize, usize) {
        self.dim()
    }

    fn value(self, y: usize, x: usize) -> f64 {
        self[[y, x]]
    }

    fn fill_line(self, y: usize, x0: usize, line: &mut [f64]) {
        let row = self.row(y);
        for (v, s) in line.iter_mut().zip(row.iter().skip(x0)) {
            *v = *s;
        }
    }

    fn part(self, rows: Range<usize>, cols: Range<usize>, factor: f64) -> Array2<f64> {
        let crop = self.slice(ndarray::s![rows, cols]);
        match factor < 1.0 {
            true => resample::downsample(crop, factor),
            false => crop.to_owned(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane that only answers pixel by pixel: the trait's own `part`.
    #[derive(Clone, Copy)]
    struct ByPixel<'a>(ArrayView2<'a, f64>);

    impl Plane for ByPixel<'_> {
        fn size(self) -> (usize, usize) {
            self.0.dim()
        }
        fn value(self, y: usize, x: usize) -> f64 {
            self.0[[y, x]]
        }
        fn fill_line(self, y: usize, x0: usize, line: &mut [f64]) {
            for (k, v) in line.iter_mut().enumerate() {
                *v = self.0[[y, x0 + k]];
            }
        }
    }

    #[test]
    fn a_part_read_line_by_line_is_the_arrays_to_the_bit() {
        let mut rng = crate::util::rng::Rng::new(3);
        let image = Array2::from_shape_fn((53, 71), |_| rng.next_f64() * 2.0);
        for (rows, cols, factor) in [
            (0..53, 0..71, 0.31),
            (4..50, 9..60, 0.5),
            (10..20, 3..40, 1.0),
            (0..53, 0..71, 0.123),
        ] {
            let lines = ByPixel(image.view()).part(rows.clone(), cols.clone(), factor);
            let array = image.view().part(rows, cols, factor);
            assert_eq!(lines.dim(), array.dim());
            assert!(
                lines
                    .iter()
                    .zip(&array)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
        }
    }
}
