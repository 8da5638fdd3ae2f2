//! PLY (ASCII, binary little- and big-endian): the `vertex` element's `x y z` (and `nx ny
//! nz` when all three are there), the `face` element's `vertex_indices` (or `vertex_index`)
//! list, split into fans; other elements and properties are read past. Counts are checked
//! against the limits and the bytes left before anything is allocated.

use super::obj::unit;
use super::{Mesh, MeshLimits, ShapeError};

fn error(line: usize, message: impl Into<String>) -> ShapeError {
    ShapeError::Parse {
        format: "PLY",
        line,
        message: message.into(),
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn bytes(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    /// `Some(count type)` for a list.
    list: Option<Scalar>,
    kind: Scalar,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Lines in the header (for messages about the body).
    lines: usize,
    /// Bytes of the header, up to and including `end_header\n`.
    length: usize,
}

/// Longest header read.
const MAX_HEADER: usize = 64 << 10;

fn header(bytes: &[u8]) -> Result<Header, ShapeError> {
    let end = find(bytes, b"end_header").ok_or_else(|| error(1, "no end_header"))?;
    if end > MAX_HEADER {
        return Err(error(1, "the header is longer than 64 KiB"));
    }
    let newline = bytes[end..]
        .iter()
        .position(|&b| b == b'\n')
        .map(|p| end + p + 1);
    let length = newline.unwrap_or(bytes.len());
    let text =
        std::str::from_utf8(&bytes[..end]).map_err(|_| error(1, "the header is not text"))?;
    let mut lines = text.lines().map(str::trim).enumerate();
    if lines.next().map(|(_, l)| l) != Some("ply") {
        return Err(error(1, "not a PLY file (no \"ply\" magic line)"));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for (index, line) in lines {
        let number = index + 1;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", f, _] => format = Some(parse_format(f, number)?),
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count
                    .parse()
                    .map_err(|_| error(number, format!("{count:?} is not a count")))?,
                properties: Vec::new(),
            }),
            ["property", ..] => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| error(number, "a property before any element"))?;
                element.properties.push(property(&words, number)?);
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            _ => return Err(error(number, format!("unexpected header line {line:?}"))),
        }
    }
    Ok(Header {
        format: format.ok_or_else(|| error(2, "no format line"))?,
        elements,
        lines: text.lines().count() + 1,
        length,
    })
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack
        .windows(needle.len())
        .take(MAX_HEADER + needle.len())
        .position(|w| w == needle)
}

fn parse_format(f: &str, line: usize) -> Result<Format, ShapeError> {
    match f {
        "ascii" => Ok(Format::Ascii),
        "binary_little_endian" => Ok(Format::Little),
        "binary_big_endian" => Ok(Format::Big),
        other => Err(error(line, format!("unknown format {other:?}"))),
    }
}

fn property(words: &[&str], line: usize) -> Result<Property, ShapeError> {
    let scalar = |name: &str| {
        Scalar::parse(name).ok_or_else(|| error(line, format!("unknown type {name:?}")))
    };
    match words {
        ["property", "list", count, kind, name] => Ok(Property {
            name: name.to_string(),
            list: Some(scalar(count)?),
            kind: scalar(kind)?,
        }),
        ["property", kind, name] => Ok(Property {
            name: name.to_string(),
            list: None,
            kind: scalar(kind)?,
        }),
        _ => Err(error(
            line,
            "a property is `property TYPE NAME` or `property list T T NAME`",
        )),
    }
}

/// Reads the body's values one at a time, as text or binary.
struct Reader<'a> {
    format: Format,
    bytes: &'a [u8],
    at: usize,
    line: usize,
}

impl Reader<'_> {
    fn value(&mut self, kind: Scalar) -> Result<f64, ShapeError> {
        match self.format {
            Format::Ascii => self.word(),
            _ => self.binary(kind),
        }
    }

    fn word(&mut self) -> Result<f64, ShapeError> {
        while let Some(&b) = self.bytes.get(self.at).filter(|b| b.is_ascii_whitespace()) {
            self.line += usize::from(b == b'\n');
            self.at += 1;
        }
        let start = self.at;
        while self
            .bytes
            .get(self.at)
            .is_some_and(|b| !b.is_ascii_whitespace())
        {
            self.at += 1;
        }
        let word = std::str::from_utf8(&self.bytes[start..self.at]).unwrap_or("");
        if word.is_empty() {
            return Err(error(self.line, "the file ends early"));
        }
        word.parse::<f64>()
            .map_err(|_| error(self.line, format!("{word:?} is not a number")))
    }

    fn binary(&mut self, kind: Scalar) -> Result<f64, ShapeError> {
        let n = kind.bytes();
        let raw = self
            .bytes
            .get(self.at..self.at + n)
            .ok_or_else(|| error(self.line, "the file ends early"))?;
        self.at += n;
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(raw);
        if self.format == Format::Big {
            b[..n].reverse();
        }
        Ok(match kind {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F64 => f64::from_le_bytes(b),
        })
    }

    /// Whether `count` more items of at least `least` bytes (binary) or 2 bytes (text) can
    /// be in what is left.
    fn room(&self, count: usize, least: usize) -> bool {
        let least = if self.format == Format::Ascii {
            2
        } else {
            least.max(1)
        };
        count.saturating_mul(least) <= self.bytes.len() - self.at.min(self.bytes.len())
    }
}

/// What the mesh is built from.
#[derive(Default)]
struct Parts {
    positions: Vec<[f64; 3]>,
    normals: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
}

pub(super) fn parse(bytes: &[u8], limits: &MeshLimits) -> Result<Mesh, ShapeError> {
    let header = header(bytes)?;
    let mut reader = Reader {
        format: header.format,
        bytes: &bytes[header.length..],
        at: 0,
        line: header.lines + 1,
    };
    let mut parts = Parts::default();
    let mut has_normals = false;
    for element in &header.elements {
        let least: usize = (element.properties.iter())
            .map(|p| p.list.unwrap_or(p.kind).bytes())
            .sum();
        if !reader.room(element.count, least) {
            return Err(error(
                header.lines,
                format!("{} {}s cannot fit in the file", element.count, element.name),
            ));
        }
        match element.name.as_str() {
            "vertex" => has_normals = vertices(&mut reader, element, limits, &mut parts)?,
            "face" => faces(&mut reader, element, limits, &mut parts)?,
            _ => skip(&mut reader, element)?,
        }
    }
    let normals = match has_normals {
        true => Some((parts.normals, parts.triangles.clone())),
        false => None,
    };
    Mesh::new(parts.positions, parts.triangles, normals)
}

/// The column of each named property in `element`, if all are there.
fn columns<const N: usize>(element: &Element, names: [&str; N]) -> Option<[usize; N]> {
    let find =
        |name: &str| (element.properties.iter()).position(|p| p.name == name && p.list.is_none());
    let found = names.map(find);
    found
        .iter()
        .all(Option::is_some)
        .then(|| found.map(|c| c.unwrap_or(0)))
}

/// Reads the vertices; whether they carry normals.
fn vertices(
    reader: &mut Reader,
    element: &Element,
    limits: &MeshLimits,
    parts: &mut Parts,
) -> Result<bool, ShapeError> {
    if element.count > limits.vertices {
        return Err(ShapeError::TooLarge(format!(
            "more than {} vertices",
            limits.vertices
        )));
    }
    let xyz = columns(element, ["x", "y", "z"])
        .ok_or_else(|| error(reader.line, "the vertex element has no x, y and z"))?;
    let normal = columns(element, ["nx", "ny", "nz"]);
    parts.positions.reserve(element.count);
    let mut row = vec![0.0; element.properties.len()];
    for _ in 0..element.count {
        for (value, p) in row.iter_mut().zip(&element.properties) {
            *value = match p.list {
                Some(count) => {
                    skip_list(reader, count, p.kind)?;
                    0.0
                }
                None => reader.value(p.kind)?,
            };
        }
        let position = xyz.map(|c| row[c]);
        if !position.iter().all(|v| v.is_finite()) {
            return Err(error(reader.line, "a vertex is not finite"));
        }
        parts.positions.push(position);
        if let Some(n) = normal {
            parts.normals.push(unit(n.map(|c| row[c])));
        }
    }
    Ok(normal.is_some())
}

fn faces(
    reader: &mut Reader,
    element: &Element,
    limits: &MeshLimits,
    parts: &mut Parts,
) -> Result<(), ShapeError> {
    let list = (element.properties.iter())
        .position(|p| p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index"))
        .ok_or_else(|| error(reader.line, "the face element has no vertex_indices list"))?;
    let mut polygon = Vec::new();
    for _ in 0..element.count {
        for (k, p) in element.properties.iter().enumerate() {
            match (p.list, k == list) {
                (Some(count), true) => polygon_of(reader, count, p.kind, &mut polygon)?,
                (Some(count), false) => skip_list(reader, count, p.kind)?,
                (None, _) => {
                    reader.value(p.kind)?;
                }
            }
        }
        fan(&polygon, parts, limits, reader.line)?;
    }
    Ok(())
}

fn polygon_of(
    reader: &mut Reader,
    count: Scalar,
    kind: Scalar,
    out: &mut Vec<u32>,
) -> Result<(), ShapeError> {
    let n = reader.value(count)?;
    if !(0.0..=1024.0).contains(&n) || n.fract() != 0.0 {
        return Err(error(
            reader.line,
            format!("a face has {n} corners (at most 1024)"),
        ));
    }
    out.clear();
    for _ in 0..n as usize {
        let v = reader.value(kind)?;
        if !(0.0..=f64::from(u32::MAX - 1)).contains(&v) || v.fract() != 0.0 {
            return Err(error(reader.line, format!("{v} is not a vertex index")));
        }
        out.push(v as u32);
    }
    Ok(())
}

fn fan(
    polygon: &[u32],
    parts: &mut Parts,
    limits: &MeshLimits,
    line: usize,
) -> Result<(), ShapeError> {
    if polygon.len() < 3 {
        return Err(error(line, "a face has fewer than 3 corners"));
    }
    if polygon.iter().any(|&v| v as usize >= parts.positions.len()) {
        return Err(error(
            line,
            format!(
                "a face names a vertex beyond the {} read",
                parts.positions.len()
            ),
        ));
    }
    for k in 1..polygon.len() - 1 {
        if parts.triangles.len() >= limits.triangles {
            return Err(ShapeError::TooLarge(format!(
                "more than {} triangles",
                limits.triangles
            )));
        }
        parts
            .triangles
            .push([polygon[0], polygon[k], polygon[k + 1]]);
    }
    Ok(())
}

fn skip_list(reader: &mut Reader, count: Scalar, kind: Scalar) -> Result<(), ShapeError> {
    let n = reader.value(count)?;
    if !(0.0..=65536.0).contains(&n) || n.fract() != 0.0 {
        return Err(error(reader.line, format!("a list of {n} items")));
    }
    for _ in 0..n as usize {
        reader.value(kind)?;
    }
    Ok(())
}

fn skip(reader: &mut Reader, element: &Element) -> Result<(), ShapeError> {
    for _ in 0..element.count {
        for p in &element.properties {
            match p.list {
                Some(count) => skip_list(reader, count, p.kind)?,
                None => {
                    reader.value(p.kind)?;
                }
            }
        }
    }
    Ok(())
}
