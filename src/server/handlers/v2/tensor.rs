//! The Open Inference Protocol's tensors, whatever carried them: JSON `data`, the HTTP
//! binary tensor data extension, or gRPC contents. Elements are held by kind (numbers as
//! f64, whatever their datatype), and written back in the datatype's own bytes.

use bytes::Bytes;

/// The protocol's tensor datatypes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Datatype {
    Bool,
    Uint8,
    Uint16,
    Uint32,
    Uint64,
    Int8,
    Int16,
    Int32,
    Int64,
    Fp16,
    Fp32,
    Fp64,
    Bytes,
}

impl Datatype {
    const ALL: [(Datatype, &'static str); 13] = [
        (Datatype::Bool, "BOOL"),
        (Datatype::Uint8, "UINT8"),
        (Datatype::Uint16, "UINT16"),
        (Datatype::Uint32, "UINT32"),
        (Datatype::Uint64, "UINT64"),
        (Datatype::Int8, "INT8"),
        (Datatype::Int16, "INT16"),
        (Datatype::Int32, "INT32"),
        (Datatype::Int64, "INT64"),
        (Datatype::Fp16, "FP16"),
        (Datatype::Fp32, "FP32"),
        (Datatype::Fp64, "FP64"),
        (Datatype::Bytes, "BYTES"),
    ];

    pub fn parse(name: &str) -> Option<Datatype> {
        Self::ALL.iter().find(|(_, n)| *n == name).map(|(d, _)| *d)
    }

    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(d, _)| *d == self)
            .map_or("BYTES", |(_, n)| n)
    }

    /// Bytes per element (None: BYTES, whose elements carry their own length).
    pub fn size(self) -> Option<usize> {
        use Datatype as D;
        Some(match self {
            D::Bool | D::Uint8 | D::Int8 => 1,
            D::Uint16 | D::Int16 | D::Fp16 => 2,
            D::Uint32 | D::Int32 | D::Fp32 => 4,
            D::Uint64 | D::Int64 | D::Fp64 => 8,
            D::Bytes => return None,
        })
    }

    pub fn is_number(self) -> bool {
        !matches!(self, Datatype::Bool | Datatype::Bytes)
    }
}

/// A tensor's elements, row-major.
#[derive(Clone, Debug, PartialEq)]
pub enum Elements {
    /// BYTES elements that arrived as bytes (binary data, gRPC).
    Bytes(Vec<Bytes>),
    /// BYTES elements that arrived as JSON strings.
    Text(Vec<String>),
    Numbers(Vec<f64>),
    Bool(Vec<bool>),
}

impl Elements {
    pub fn len(&self) -> usize {
        match self {
            Elements::Bytes(v) => v.len(),
            Elements::Text(v) => v.len(),
            Elements::Numbers(v) => v.len(),
            Elements::Bool(v) => v.len(),
        }
    }

    /// `len` elements from `start` (the caller keeps within [`Elements::len`]).
    pub fn range(&self, start: usize, len: usize) -> Elements {
        let r = start..start + len;
        match self {
            Elements::Bytes(v) => Elements::Bytes(v[r].to_vec()),
            Elements::Text(v) => Elements::Text(v[r].to_vec()),
            Elements::Numbers(v) => Elements::Numbers(v[r].to_vec()),
            Elements::Bool(v) => Elements::Bool(v[r].to_vec()),
        }
    }

    /// `other`'s elements after these (of the same kind; another kind is left out).
    pub fn append(&mut self, other: Elements) {
        match (self, other) {
            (Elements::Bytes(v), Elements::Bytes(o)) => v.extend(o),
            (Elements::Text(v), Elements::Text(o)) => v.extend(o),
            (Elements::Numbers(v), Elements::Numbers(o)) => v.extend(o),
            (Elements::Bool(v), Elements::Bool(o)) => v.extend(o),
            _ => {}
        }
    }

    /// The elements in the protocol's raw form of `datatype`: little-endian values, BOOL
    /// as one byte, BYTES as a 4-byte little-endian length before each element.
    pub fn to_raw(&self, datatype: Datatype) -> Vec<u8> {
        let mut out = Vec::new();
        match self {
            Elements::Bytes(v) => {
                for e in v {
                    out.extend_from_slice(&(e.len() as u32).to_le_bytes());
                    out.extend_from_slice(e);
                }
            }
            Elements::Text(v) => {
                for e in v {
                    out.extend_from_slice(&(e.len() as u32).to_le_bytes());
                    out.extend_from_slice(e.as_bytes());
                }
            }
            Elements::Bool(v) => out.extend(v.iter().map(|&b| u8::from(b))),
            Elements::Numbers(v) => {
                for &x in v {
                    write_number(&mut out, datatype, x);
                }
            }
        }
        out
    }

    /// Elements of `datatype` from their raw form (see [`Elements::to_raw`]).
    pub fn from_raw(datatype: Datatype, raw: &Bytes) -> Result<Elements, TensorError> {
        let Some(size) = datatype.size() else {
            return bytes_elements(raw).map(Elements::Bytes);
        };
        if !raw.len().is_multiple_of(size) {
            return Err(TensorError::Ragged {
                bytes: raw.len(),
                datatype: datatype.name(),
            });
        }
        let chunks = raw.chunks_exact(size);
        Ok(match datatype {
            Datatype::Bool => Elements::Bool(chunks.map(|c| c[0] != 0).collect()),
            _ => Elements::Numbers(chunks.map(|c| read_number(datatype, c)).collect()),
        })
    }
}

/// Raw tensor contents that do not hold whole elements of their datatype.
#[derive(Debug, thiserror::Error)]
pub enum TensorError {
    #[error("{bytes} bytes are not a whole number of {datatype} elements")]
    Ragged {
        bytes: usize,
        datatype: &'static str,
    },
    #[error("a BYTES element's 4-byte length is cut short")]
    LengthCut,
    #[error("a BYTES element says {length} bytes, but {remain} remain")]
    ElementCut { length: usize, remain: usize },
    #[error("FP16 travels as raw contents only")]
    TypedFp16,
    #[error("no contents")]
    Empty,
    /// JSON `data` with a value the datatype cannot hold.
    #[error("is {datatype}, but holds {value}")]
    Holds {
        datatype: &'static str,
        value: String,
    },
}

fn bytes_elements(raw: &Bytes) -> Result<Vec<Bytes>, TensorError> {
    let mut elements = Vec::new();
    let mut at = 0;
    while at < raw.len() {
        let Some(length) = raw.get(at..at + 4) else {
            return Err(TensorError::LengthCut);
        };
        let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]) as usize;
        let start = at + 4;
        if raw.len() - start < length {
            return Err(TensorError::ElementCut {
                length,
                remain: raw.len() - start,
            });
        }
        elements.push(raw.slice(start..start + length));
        at = start + length;
    }
    Ok(elements)
}

/// One element of `datatype` from its `size()` little-endian bytes.
fn read_number(datatype: Datatype, c: &[u8]) -> f64 {
    let mut padded = [0u8; 8];
    let n = c.len().min(8);
    padded[..n].copy_from_slice(&c[..n]);
    let [b0, b1, b2, b3, ..] = padded;
    match datatype {
        Datatype::Uint8 => f64::from(b0),
        Datatype::Int8 => f64::from(b0 as i8),
        Datatype::Uint16 => f64::from(u16::from_le_bytes([b0, b1])),
        Datatype::Int16 => f64::from(i16::from_le_bytes([b0, b1])),
        Datatype::Fp16 => half_to_f64(u16::from_le_bytes([b0, b1])),
        Datatype::Uint32 => f64::from(u32::from_le_bytes([b0, b1, b2, b3])),
        Datatype::Int32 => f64::from(i32::from_le_bytes([b0, b1, b2, b3])),
        Datatype::Fp32 => f64::from(f32::from_le_bytes([b0, b1, b2, b3])),
        Datatype::Uint64 => u64::from_le_bytes(padded) as f64,
        Datatype::Int64 => i64::from_le_bytes(padded) as f64,
        Datatype::Fp64 => f64::from_le_bytes(padded),
        Datatype::Bool | Datatype::Bytes => f64::NAN,
    }
}

fn write_number(out: &mut Vec<u8>, datatype: Datatype, x: f64) {
    match datatype {
        Datatype::Uint8 => out.push(x as u8),
        Datatype::Int8 => out.push(x as i8 as u8),
        Datatype::Uint16 => out.extend((x as u16).to_le_bytes()),
        Datatype::Int16 => out.extend((x as i16).to_le_bytes()),
        Datatype::Fp16 => out.extend(f64_to_half(x).to_le_bytes()),
        Datatype::Uint32 => out.extend((x as u32).to_le_bytes()),
        Datatype::Int32 => out.extend((x as i32).to_le_bytes()),
        Datatype::Fp32 => out.extend((x as f32).to_le_bytes()),
        Datatype::Uint64 => out.extend((x as u64).to_le_bytes()),
        Datatype::Int64 => out.extend((x as i64).to_le_bytes()),
        Datatype::Fp64 | Datatype::Bool | Datatype::Bytes => out.extend(x.to_le_bytes()),
    }
}

/// IEEE 754 binary16 to f64.
fn half_to_f64(h: u16) -> f64 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exponent = i32::from((h >> 10) & 0x1f);
    let fraction = f64::from(h & 0x3ff);
    sign * match exponent {
        0 => fraction * 2f64.powi(-24),
        31 if fraction == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        e => (1.0 + fraction / 1024.0) * 2f64.powi(e - 15),
    }
}

/// f64 to the nearest binary16 (ties to even; beyond its range, infinity).
fn f64_to_half(x: f64) -> u16 {
    let sign = if x.is_sign_negative() { 0x8000 } else { 0 };
    let a = x.abs();
    if a.is_nan() {
        return 0x7e00;
    }
    if a >= 65520.0 {
        return sign | 0x7c00;
    }
    if a < 2f64.powi(-14) {
        // Subnormal (a result of 1024 is the least normal number's encoding).
        return sign | (a * 2f64.powi(24)).round_ties_even() as u16;
    }
    let mut exponent = a.log2().floor() as i32;
    let mut mantissa = ((a / 2f64.powi(exponent) - 1.0) * 1024.0).round_ties_even() as u16;
    if mantissa == 1024 {
        exponent += 1;
        mantissa = 0;
    }
    sign | (((exponent + 15) as u16) << 10) | mantissa
}

/// A named tensor.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    pub name: String,
    pub datatype: Datatype,
    pub shape: Vec<i64>,
    pub elements: Elements,
}

impl Tensor {
    pub fn bytes(name: &str, values: Vec<String>) -> Tensor {
        Tensor {
            name: name.into(),
            datatype: Datatype::Bytes,
            shape: vec![values.len() as i64],
            elements: Elements::Text(values),
        }
    }

    pub fn fp64(name: &str, shape: Vec<i64>, values: Vec<f64>) -> Tensor {
        Tensor {
            name: name.into(),
            datatype: Datatype::Fp64,
            shape,
            elements: Elements::Numbers(values),
        }
    }

    pub fn bool(name: &str, value: bool) -> Tensor {
        Tensor {
            name: name.into(),
            datatype: Datatype::Bool,
            shape: vec![1],
            elements: Elements::Bool(vec![value]),
        }
    }

    /// Elements the shape announces (None: a negative or overflowing dimension).
    pub fn announced(shape: &[i64]) -> Option<usize> {
        shape.iter().try_fold(1usize, |n, &d| {
            usize::try_from(d).ok().and_then(|d| n.checked_mul(d))
        })
    }

    /// A request's input as a tensor, whatever carried it (JSON, binary data, gRPC): its
    /// datatype named by the protocol, its elements read as that datatype, as many as its
    /// shape announces.
    pub fn input(
        name: String,
        datatype: &str,
        shape: Vec<i64>,
        elements: impl FnOnce(Datatype) -> Result<Elements, TensorError>,
    ) -> Result<Tensor, InputError> {
        let Some(datatype) = Datatype::parse(datatype) else {
            let datatype = datatype.to_string();
            return Err(InputError::Datatype { name, datatype });
        };
        let elements = match elements(datatype) {
            Ok(elements) => elements,
            Err(source) => return Err(InputError::Contents { name, source }),
        };
        if Tensor::announced(&shape) != Some(elements.len()) {
            let count = elements.len();
            return Err(InputError::Shape { name, count, shape });
        }
        Ok(Tensor {
            name,
            datatype,
            shape,
            elements,
        })
    }
}

/// A contents error as it reads after the input's name.
fn after_name(e: &TensorError) -> String {
    match e {
        TensorError::Holds { .. } => format!(" {e}"),
        _ => format!(": {e}"),
    }
}

/// Why a request's input is not a tensor: the same words over HTTP and gRPC.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("input {name:?} has no datatype {datatype:?}")]
    Datatype { name: String, datatype: String },
    #[error("input {name:?}{}", after_name(source))]
    Contents { name: String, source: TensorError },
    #[error("input {name:?} holds {count} elements, but its shape is {shape:?}")]
    Shape {
        name: String,
        count: usize,
        shape: Vec<i64>,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raw_elements_round_trip_in_every_datatype() {
        let numbers = vec![0.0, 1.0, 2.0, 100.0];
        for (datatype, _) in Datatype::ALL {
            let elements = match datatype {
                Datatype::Bool => Elements::Bool(vec![true, false, true]),
                Datatype::Bytes => Elements::Bytes(vec![
                    Bytes::from_static(b"ab"),
                    Bytes::new(),
                    Bytes::from_static(b"\xff"),
                ]),
                _ => Elements::Numbers(numbers.clone()),
            };
            let raw = Bytes::from(elements.to_raw(datatype));
            assert_eq!(
                Elements::from_raw(datatype, &raw).unwrap(),
                elements,
                "{datatype:?}"
            );
        }
    }

    /// Known answers: the protocol's BYTES framing, and binary16's bits.
    #[test]
    fn raw_forms_are_the_protocols() {
        let raw = Elements::Text(vec!["chrome".into()]).to_raw(Datatype::Bytes);
        assert_eq!(raw, b"\x06\x00\x00\x00chrome");
        assert_eq!(
            Elements::Numbers(vec![1.0]).to_raw(Datatype::Fp64),
            1f64.to_le_bytes()
        );
        assert_eq!(
            Elements::Numbers(vec![-2.5]).to_raw(Datatype::Fp16),
            [0x00, 0xc1]
        );
        assert_eq!(half_to_f64(0x3c00), 1.0);
        assert_eq!(half_to_f64(0x3555), 0.333251953125);
        assert_eq!(half_to_f64(0x0001), 2f64.powi(-24));
        assert_eq!(f64_to_half(65504.0), 0x7bff);
        assert_eq!(f64_to_half(1e6), 0x7c00);
    }

    #[test]
    fn malformed_raw_data_is_refused() {
        let cut = Bytes::from_static(b"\x05\x00\x00\x00abc");
        assert!(Elements::from_raw(Datatype::Bytes, &cut).is_err());
        assert!(Elements::from_raw(Datatype::Bytes, &Bytes::from_static(b"\x01\x00")).is_err());
        assert!(Elements::from_raw(Datatype::Fp32, &Bytes::from_static(b"\x00\x00\x00")).is_err());
    }

    #[test]
    fn shapes_announce_their_element_count() {
        assert_eq!(Tensor::announced(&[1]), Some(1));
        assert_eq!(Tensor::announced(&[1, 3]), Some(3));
        assert_eq!(Tensor::announced(&[]), Some(1));
        assert_eq!(Tensor::announced(&[-1]), None);
        assert_eq!(Tensor::announced(&[i64::MAX, i64::MAX]), None);
    }
}
