//! Wavefront OBJ: `v` positions, `vn` normals, `f` polygons (`v`, `v/t`, `v//n`, `v/t/n`,
//! negative indices relative to the end), split into fans; everything else ignored. The
//! file's normals are used when every corner of every face names one.

use super::{Mesh, MeshLimits, ShapeError};

fn error(line: usize, message: impl Into<String>) -> ShapeError {
    ShapeError::Parse {
        format: "OBJ",
        line,
        message: message.into(),
    }
}

#[derive(Default)]
struct Builder {
    positions: Vec<[f64; 3]>,
    normals: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    corners: Vec<[u32; 3]>,
    /// Whether every corner so far named a normal.
    all_normals: bool,
}

pub(super) fn parse(bytes: &[u8], limits: &MeshLimits) -> Result<Mesh, ShapeError> {
    let text = std::str::from_utf8(bytes).map_err(|e| error(0, format!("not UTF-8 text: {e}")))?;
    let mut b = Builder {
        all_normals: true,
        ..Builder::default()
    };
    for (index, line) in text.lines().enumerate() {
        let number = index + 1;
        let line = line.split('#').next().unwrap_or("");
        let mut fields = line.split_whitespace();
        match fields.next() {
            Some("v") => {
                if b.positions.len() >= limits.vertices {
                    return Err(too_many("vertices", limits.vertices));
                }
                b.positions.push(numbers(fields, number)?);
            }
            Some("vn") => {
                if b.normals.len() >= limits.vertices {
                    return Err(too_many("normals", limits.vertices));
                }
                b.normals.push(unit(numbers(fields, number)?));
            }
            Some("f") => face(&mut b, fields, number, limits)?,
            _ => {}
        }
    }
    let normals = match b.all_normals && !b.triangles.is_empty() {
        true => Some((b.normals, b.corners)),
        false => None,
    };
    Mesh::new(b.positions, b.triangles, normals)
}

fn too_many(what: &str, limit: usize) -> ShapeError {
    ShapeError::TooLarge(format!("more than {limit} {what}"))
}

/// The first three numbers of a line (a `w` or colour after them ignored).
fn numbers<'a>(
    mut fields: impl Iterator<Item = &'a str>,
    line: usize,
) -> Result<[f64; 3], ShapeError> {
    let mut out = [0.0; 3];
    for value in &mut out {
        let field = fields
            .next()
            .ok_or_else(|| error(line, "fewer than 3 coordinates"))?;
        *value = field
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| error(line, format!("{field:?} is not a finite number")))?;
    }
    Ok(out)
}

/// A normal scaled to unit length ([0, 0, 0] stays, and is replaced by the face's later).
pub(super) fn unit(n: [f64; 3]) -> [f32; 3] {
    let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    match length > 0.0 {
        true => n.map(|c| (c / length) as f32),
        false => [0.0; 3],
    }
}

/// A 1-based (or negative, from the end) OBJ index into a list of `count`.
fn resolve(field: &str, count: usize, line: usize) -> Result<u32, ShapeError> {
    let k: i64 = field
        .parse()
        .map_err(|_| error(line, format!("{field:?} is not an index")))?;
    let index = match k {
        k if k > 0 => k - 1,
        k if k < 0 => count as i64 + k,
        _ => -1,
    };
    match usize::try_from(index) {
        Ok(i) if i < count => Ok(i as u32),
        _ => Err(error(
            line,
            format!("index {k} is out of range (1…{count})"),
        )),
    }
}

fn face<'a>(
    b: &mut Builder,
    fields: impl Iterator<Item = &'a str>,
    line: usize,
    limits: &MeshLimits,
) -> Result<(), ShapeError> {
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    for field in fields {
        if corners.len() >= 1024 {
            return Err(error(line, "a face has more than 1024 corners"));
        }
        let mut parts = field.split('/');
        let v = resolve(parts.next().unwrap_or(""), b.positions.len(), line)?;
        let n = match parts.nth(1) {
            Some(n) if !n.is_empty() => Some(resolve(n, b.normals.len(), line)?),
            _ => None,
        };
        corners.push((v, n));
    }
    if corners.len() < 3 {
        return Err(error(line, "a face has fewer than 3 corners"));
    }
    for k in 1..corners.len() - 1 {
        if b.triangles.len() >= limits.triangles {
            return Err(too_many("triangles", limits.triangles));
        }
        let fan = [corners[0], corners[k], corners[k + 1]];
        b.triangles.push(fan.map(|c| c.0));
        match fan.map(|c| c.1) {
            [Some(a), Some(bb), Some(c)] => b.corners.push([a, bb, c]),
            _ => b.all_normals = false,
        }
    }
    Ok(())
}
