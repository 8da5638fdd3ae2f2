//! Where one pixel of an object lands on its equivalent sphere, and the weights it spreads
//! there with (the equivalent sphere of `normals.rs`).

/// Where one pixel lands on the equivalent sphere: centred `at` (cell coordinates), with
/// `across` and `down` the sphere positions of half the way to its neighbours. Its value
/// spreads with tent weights over the parallelogram reaching its neighbours' centres (so
/// neighbouring pixels interpolate, as bilinear resampling does, and an object with fewer
/// pixels than the sphere has cells leaves no holes between them); a pixel smaller than a
/// cell spreads over the four cells around it, bilinearly.
#[derive(Clone, Debug)]
pub struct Footprint {
    /// The sphere position of the pixel's normal.
    pub at: [f64; 2],
    /// Half the step to the next pixel across.
    pub across: [f64; 2],
    /// Half the step to the next pixel down.
    pub down: [f64; 2],
}

/// Cells a footprint reaches at most on each side of its centre (a pixel whose normal turns
/// faster is at a crease, where the edge rule of the equivalent sphere leaves it out anyway).
const MAX_REACH: f64 = 8.0;

/// A footprint's weight at any point ([`Footprint::weights`]).
pub struct Weights {
    at: [f64; 2],
    to_steps: Option<[f64; 4]>,
}

impl Weights {
    /// The weight at the point (x, y).
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.at[0], y - self.at[1]);
        let (s, t) = match self.to_steps {
            Some([a, b, c, d]) => (a * dx + b * dy, c * dx + d * dy),
            None => (dx, dy),
        };
        (1.0 - s.abs()).max(0.0) * (1.0 - t.abs()).max(0.0)
    }
}

impl Footprint {
    /// How far the tent reaches from `at` along the unit direction `u` (at most
    /// [`MAX_REACH`]); a degenerate footprint spreads a cell each way along the axes.
    pub fn extent(&self, u: [f64; 2]) -> f64 {
        if self.degenerate() {
            return u[0].abs() + u[1].abs();
        }
        let along = |v: [f64; 2]| (v[0] * u[0] + v[1] * u[1]).abs();
        (2.0 * (along(self.across) + along(self.down))).min(MAX_REACH)
    }

    fn det(&self) -> f64 {
        self.across[0] * self.down[1] - self.across[1] * self.down[0]
    }

    /// Whether the footprint spans no area (its neighbours' normals are its own or in line),
    /// so that it can only spread bilinearly.
    pub fn degenerate(&self) -> bool {
        self.det().abs() < 1e-9
    }

    /// Its weights: the tent, 1 at the centre and 0 at and past the neighbours' centres; or,
    /// when `bilinear` or degenerate, those of a point spread over the cells around it.
    pub fn weights(&self, bilinear: bool) -> Weights {
        let det = self.det();
        if bilinear || det.abs() < 1e-9 {
            return Weights {
                at: self.at,
                to_steps: None,
            };
        }
        // (dx, dy) ↦ the point in pixel steps along the two sides (s, t ∈ [−1, 1]).
        let k = 0.5 / det;
        Weights {
            at: self.at,
            to_steps: Some([
                k * self.down[1],
                -k * self.down[0],
                -k * self.across[1],
                k * self.across[0],
            ]),
        }
    }

    /// Call `visit` with the index and weight of each cell of a `side`-wide grid the
    /// footprint covers.
    pub(crate) fn cover(&self, side: usize, mut visit: impl FnMut(usize, f64)) {
        let [x, y] = self.at;
        let (reach_x, reach_y) = (self.extent([1.0, 0.0]), self.extent([0.0, 1.0]));
        let last = (side - 1) as f64;
        let mut put = |cx: f64, cy: f64, w: f64| {
            if w > 0.0 && (0.0..=last).contains(&cx) && (0.0..=last).contains(&cy) {
                visit(cy as usize * side + cx as usize, w);
            }
        };
        let small = reach_x < 1.0 && reach_y < 1.0 || self.degenerate();
        let (reach_x, reach_y) = if small {
            (1.0, 1.0)
        } else {
            (reach_x, reach_y)
        };
        let weights = self.weights(small);
        let (x0, x1) = ((x - reach_x).ceil(), (x + reach_x).floor());
        let (y0, y1) = ((y - reach_y).ceil(), (y + reach_y).floor());
        let mut cy = y0;
        while cy <= y1 {
            let mut cx = x0;
            while cx <= x1 {
                put(cx, cy, weights.at(cx, cy));
                cx += 1.0;
            }
            cy += 1.0;
        }
    }
}
