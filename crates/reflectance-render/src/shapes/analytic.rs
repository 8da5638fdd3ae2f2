//! Analytic shapes by ray casting: an implicit function f (negative inside) per shape,
//! marched along the camera's rays (safe steps where f bounds the distance), the crossing
//! bisected, the normal its gradient's direction.

use super::{Pose, Raster, Shape, ShapeError, facing};
use crate::{Vec3, sphere_normal};
use reflectance_core::util::rng::Rng;

/// One metaball: a Wyvill field w·(1 − d²/R²)³ within R of its centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ball {
    /// Centre.
    pub centre: [f64; 3],
    /// Radius of influence R > 0.
    pub radius: f64,
    /// Weight w > 0.
    pub weight: f64,
}

/// Metaballs: the surface where their summed field equals `threshold`.
#[derive(Clone, Debug, PartialEq)]
pub struct Blob {
    /// The balls (1…16).
    pub balls: Vec<Ball>,
    /// The iso-level, in (0, 1).
    pub threshold: f64,
}

impl Blob {
    /// `count` balls (1…16) of radius 0.5…0.8 with centres within 0.6 of the origin, drawn
    /// from `seed`, at threshold 0.3.
    pub fn seeded(seed: u64, count: usize) -> Blob {
        let mut rng = Rng::fork(seed, 0x626c_6f62);
        let balls = (0..count.clamp(1, 16))
            .map(|_| {
                let centre = loop {
                    let c = [0; 3].map(|_| 1.2 * rng.next_f64() - 0.6);
                    if c.iter().map(|v| v * v).sum::<f64>() <= 0.6 * 0.6 {
                        break c;
                    }
                };
                Ball {
                    centre,
                    radius: 0.5 + 0.3 * rng.next_f64(),
                    weight: 1.0,
                }
            })
            .collect();
        Blob {
            balls,
            threshold: 0.3,
        }
    }

    fn check(&self) -> Result<(), ShapeError> {
        let ball_ok = |b: &Ball| {
            b.centre.iter().all(|c| c.is_finite())
                && b.radius > 0.0
                && b.radius.is_finite()
                && b.weight > 0.0
                && b.weight.is_finite()
        };
        let valid = (1..=16).contains(&self.balls.len())
            && self.balls.iter().all(ball_ok)
            && self.threshold > 0.0
            && self.threshold < 1.0;
        if !valid {
            return Err(ShapeError::Parameter(
                "a blob has 1…16 balls of finite centre, positive radius and weight, and a \
                 threshold in (0, 1)"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// An implicit surface in its own frame.
trait Implicit {
    /// Negative inside, positive outside.
    fn value(&self, p: Vec3) -> f64;
    /// The gradient of [`Implicit::value`] (any length).
    fn gradient(&self, p: Vec3) -> Vec3;
    /// A lower bound on the distance from `p` to the surface, if one is known.
    fn distance_bound(&self, p: Vec3) -> Option<f64>;
    /// The radius of a sphere about the origin holding the shape.
    fn radius(&self) -> f64;
}

struct Torus {
    major: f64,
    minor: f64,
}

impl Implicit for Torus {
    fn value(&self, p: Vec3) -> f64 {
        (p.x.hypot(p.y) - self.major).hypot(p.z) - self.minor
    }
    fn gradient(&self, p: Vec3) -> Vec3 {
        let rho = p.x.hypot(p.y);
        let core = match rho > 0.0 {
            true => Vec3::new(p.x, p.y, 0.0) * (self.major / rho),
            false => Vec3::new(self.major, 0.0, 0.0),
        };
        p - core
    }
    fn distance_bound(&self, p: Vec3) -> Option<f64> {
        Some(self.value(p).abs())
    }
    fn radius(&self) -> f64 {
        self.major + self.minor
    }
}

struct Capsule {
    half_length: f64,
    radius: f64,
}

impl Capsule {
    fn axis_point(&self, p: Vec3) -> Vec3 {
        Vec3::new(0.0, p.y.clamp(-self.half_length, self.half_length), 0.0)
    }
}

impl Implicit for Capsule {
    fn value(&self, p: Vec3) -> f64 {
        let d = p - self.axis_point(p);
        d.dot(d).sqrt() - self.radius
    }
    fn gradient(&self, p: Vec3) -> Vec3 {
        p - self.axis_point(p)
    }
    fn distance_bound(&self, p: Vec3) -> Option<f64> {
        Some(self.value(p).abs())
    }
    fn radius(&self) -> f64 {
        self.half_length + self.radius
    }
}

struct Superquadric {
    axes: [f64; 3],
    /// (north-south, east-west).
    exponents: [f64; 2],
    radius: f64,
}

impl Superquadric {
    fn new(axes: [f64; 3], exponents: [f64; 2]) -> Superquadric {
        let mut shape = Superquadric {
            axes,
            exponents,
            radius: 0.0,
        };
        shape.radius = farthest(|d| 1.0 / shape.homogeneous(d));
        shape
    }

    /// F^(n/2): homogeneous of degree 1, 1 on the surface.
    fn homogeneous(&self, p: Vec3) -> f64 {
        let [n, e] = self.exponents;
        let [a, b, c] = self.axes;
        let xy = (p.x / a).abs().powf(2.0 / e) + (p.y / b).abs().powf(2.0 / e);
        (xy.powf(e / n) + (p.z / c).abs().powf(2.0 / n)).powf(n / 2.0)
    }
}

impl Implicit for Superquadric {
    fn value(&self, p: Vec3) -> f64 {
        self.homogeneous(p) - 1.0
    }
    fn gradient(&self, p: Vec3) -> Vec3 {
        let [n, e] = self.exponents;
        let [a, b, c] = self.axes;
        let power = |v: f64, k: f64| v.abs().powf(k) * v.signum();
        let xy = (p.x / a).abs().powf(2.0 / e) + (p.y / b).abs().powf(2.0 / e);
        let outer = xy.powf(e / n - 1.0);
        let g = Vec3::new(
            outer * power(p.x / a, 2.0 / e - 1.0) / a,
            outer * power(p.y / b, 2.0 / e - 1.0) / b,
            power(p.z / c, 2.0 / n - 1.0) / c,
        );
        let finite = g.x.is_finite() && g.y.is_finite() && g.z.is_finite();
        match finite && g.dot(g) > 0.0 {
            true => g,
            false => numeric_gradient(self, p),
        }
    }
    fn distance_bound(&self, _: Vec3) -> Option<f64> {
        None
    }
    fn radius(&self) -> f64 {
        self.radius
    }
}

struct Metaballs {
    blob: Blob,
    /// Σ w·1.7173/R: a Lipschitz constant of the field.
    lipschitz: f64,
    radius: f64,
}

impl Metaballs {
    fn new(blob: &Blob) -> Metaballs {
        let lipschitz = blob
            .balls
            .iter()
            .map(|b| b.weight * 1.7173 / b.radius)
            .sum();
        let mut shape = Metaballs {
            blob: blob.clone(),
            lipschitz,
            radius: 0.0,
        };
        shape.radius = shape.outer_radius();
        shape
    }

    fn field(&self, p: Vec3) -> f64 {
        self.blob
            .balls
            .iter()
            .map(|b| {
                let d = p - Vec3::new(b.centre[0], b.centre[1], b.centre[2]);
                let s = d.dot(d) / (b.radius * b.radius);
                if s < 1.0 {
                    b.weight * (1.0 - s).powi(3)
                } else {
                    0.0
                }
            })
            .sum()
    }

    /// The farthest surface point from the origin, marching in from outside every ball.
    fn outer_radius(&self) -> f64 {
        let reach = |b: &Ball| Vec3::new(b.centre[0], b.centre[1], b.centre[2]);
        let bound = (self.blob.balls.iter())
            .map(|b| reach(b).dot(reach(b)).sqrt() + b.radius)
            .fold(0.0, f64::max);
        let along = |d: Vec3| {
            let step = bound / 400.0;
            let mut t = bound;
            while t > 0.0 && self.value(d * t) >= 0.0 {
                t -= step;
            }
            t + step
        };
        farthest(along).min(bound)
    }
}

impl Implicit for Metaballs {
    fn value(&self, p: Vec3) -> f64 {
        self.blob.threshold - self.field(p)
    }
    fn gradient(&self, p: Vec3) -> Vec3 {
        let mut g = Vec3::new(0.0, 0.0, 0.0);
        for b in &self.blob.balls {
            let d = p - Vec3::new(b.centre[0], b.centre[1], b.centre[2]);
            let r2 = b.radius * b.radius;
            let s = d.dot(d) / r2;
            if s < 1.0 {
                g = g + d * (6.0 * b.weight * (1.0 - s).powi(2) / r2);
            }
        }
        g
    }
    fn distance_bound(&self, p: Vec3) -> Option<f64> {
        Some(self.value(p).abs() / self.lipschitz)
    }
    fn radius(&self) -> f64 {
        self.radius
    }
}

/// Central differences, for the rare points where a closed form is singular.
fn numeric_gradient(shape: &impl Implicit, p: Vec3) -> Vec3 {
    let h = 1e-6 * shape.radius().max(1e-300);
    let axis = |u: Vec3| shape.value(p + u * h) - shape.value(p - u * h);
    Vec3::new(
        axis(Vec3::new(1.0, 0.0, 0.0)),
        axis(Vec3::new(0.0, 1.0, 0.0)),
        axis(Vec3::new(0.0, 0.0, 1.0)),
    )
}

/// The largest of `radial(d)` over 4096 directions of a Fibonacci sphere, the axes and the
/// diagonals (with 0.1 % to spare for the directions between).
fn farthest(radial: impl Fn(Vec3) -> f64) -> f64 {
    let count = 4096;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let fibonacci = (0..count).map(|i| {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
        let r = (1.0 - z * z).sqrt();
        let phi = golden * i as f64;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    });
    let sign = |bit: usize| if bit == 0 { -1.0 } else { 1.0 };
    let diagonals =
        (0..8).map(|k| Vec3::new(sign(k & 1), sign(k >> 1 & 1), sign(k >> 2)).normalized());
    let axes = (0..6).map(|k| {
        let s = sign(k % 2);
        match k / 2 {
            0 => Vec3::new(s, 0.0, 0.0),
            1 => Vec3::new(0.0, s, 0.0),
            _ => Vec3::new(0.0, 0.0, s),
        }
    });
    let directions = fibonacci.chain(diagonals).chain(axes);
    1.001
        * directions
            .map(radial)
            .filter(|r| r.is_finite())
            .fold(0.0, f64::max)
}

/// An analytic shape ready to cast rays at, scaled to the unit sphere.
pub(crate) struct Caster {
    shape: Option<Box<dyn Implicit + Sync>>,
    pose: Pose,
    /// Shape units per camera unit (the shape's bounding radius).
    radius: f64,
}

fn positive(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite() && *v > 0.0)
}

fn implicit(shape: &Shape) -> Result<Option<Box<dyn Implicit + Sync>>, ShapeError> {
    let bad = |what: &str| Err(ShapeError::Parameter(what.to_string()));
    Ok(Some(match shape {
        Shape::Sphere => return Ok(None),
        &Shape::Torus { major, minor } => {
            if !positive(&[major, minor]) || minor > major {
                return bad("a torus has 0 < minor ≤ major");
            }
            Box::new(Torus { major, minor })
        }
        &Shape::Superquadric { axes, exponents } => {
            if !positive(&axes) || !exponents.iter().all(|e| (0.1..=2.0).contains(e)) {
                return bad("a superquadric has positive axes and exponents in 0.1…2");
            }
            Box::new(Superquadric::new(axes, exponents))
        }
        &Shape::Capsule {
            half_length,
            radius,
        } => {
            if !(positive(&[radius]) && half_length >= 0.0 && half_length.is_finite()) {
                return bad("a capsule has half_length ≥ 0 and radius > 0");
            }
            Box::new(Capsule {
                half_length,
                radius,
            })
        }
        Shape::Blob(blob) => {
            blob.check()?;
            Box::new(Metaballs::new(blob))
        }
        Shape::Mesh(_) => return bad("a mesh is rasterized, not ray cast"),
    }))
}

/// Steps of the march across the bounding sphere where the shape gives no distance bound.
const MARCH_STEPS: f64 = 256.0;
/// Bisections of a crossing (the bracket shrinks to 2⁻⁴⁸ of a step).
const BISECTIONS: usize = 48;

impl Caster {
    pub(crate) fn new(shape: &Shape, pose: &Pose) -> Result<Caster, ShapeError> {
        let shape = implicit(shape)?;
        let radius = shape.as_ref().map_or(1.0, |s| s.radius());
        if !(radius.is_finite() && radius > 0.0) {
            return Err(ShapeError::Parameter("the shape has no extent".into()));
        }
        Ok(Caster {
            shape,
            pose: *pose,
            radius,
        })
    }

    /// The first crossing of the ray `origin + t·dir` (shape frame, |dir| = 1) with the
    /// surface, t within the bounding sphere.
    fn march(&self, shape: &dyn Implicit, origin: Vec3, dir: Vec3) -> Option<Vec3> {
        let reach = 1.001 * self.radius;
        let b = origin.dot(dir);
        let disc = b * b - (origin.dot(origin) - reach * reach);
        if disc <= 0.0 {
            return None;
        }
        let (mut t, end) = (-b - disc.sqrt(), -b + disc.sqrt());
        let least = 2.0 * reach / MARCH_STEPS;
        if shape.value(origin + dir * t) < 0.0 {
            return Some(origin + dir * t);
        }
        while t < end {
            let bound = shape.distance_bound(origin + dir * t);
            let step = bound.map_or(least, |d| d.clamp(least * 1e-3, least));
            let next = (t + step).min(end);
            if shape.value(origin + dir * next) < 0.0 {
                return Some(bisect(shape, origin, dir, t, next));
            }
            t = next;
        }
        None
    }
}

/// The crossing within [t0, t1] (outside at t0, inside at t1).
fn bisect(shape: &dyn Implicit, origin: Vec3, dir: Vec3, t0: f64, t1: f64) -> Vec3 {
    let (mut lo, mut hi) = (t0, t1);
    for _ in 0..BISECTIONS {
        let mid = 0.5 * (lo + hi);
        match shape.value(origin + dir * mid) < 0.0 {
            true => hi = mid,
            false => lo = mid,
        }
    }
    origin + dir * (0.5 * (lo + hi))
}

impl Raster for Caster {
    fn normal_at(&self, x: f64, y: f64) -> Option<Vec3> {
        let Some(shape) = &self.shape else {
            return sphere_normal(x, y);
        };
        let origin = self.pose.invert(Vec3::new(x, y, 2.0)) * self.radius;
        let dir = self.pose.invert(Vec3::new(0.0, 0.0, -1.0));
        let hit = self.march(shape.as_ref(), origin, dir)?;
        let g = shape.gradient(hit);
        facing(self.pose.apply(g.normalized()))
    }
}
