//! Fixtures and tiny image encoders for the tests of every package: crafted PNG headers,
//! spheres, CRCs. (No crate of the workspace: the core's tests include it too.)
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// The repository's root, from any package of the workspace: the first folder up from the
/// package's own that holds `Cargo.lock`.
pub fn repository() -> PathBuf {
    let package = Path::new(env!("CARGO_MANIFEST_DIR"));
    package
        .ancestors()
        .find(|d| d.join("Cargo.lock").is_file())
        .unwrap_or(package)
        .to_path_buf()
}

/// The test fixtures (`tests/fixtures` at the repository's root).
pub fn fixtures() -> PathBuf {
    repository().join("tests/fixtures")
}

/// The project's development data, `../shared` beside the repository (or where
/// `REFLECTANCE_SHARED` says: a worktree kept elsewhere).
pub fn shared() -> PathBuf {
    std::env::var_os("REFLECTANCE_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| repository().join("../shared"))
}

/// Encode 8-bit samples as PNG (`channels` = 1, 2, 3 or 4).
pub fn png8(width: u32, height: u32, channels: u8, samples: &[u8]) -> Vec<u8> {
    let color = match channels {
        1 => image::ExtendedColorType::L8,
        2 => image::ExtendedColorType::La8,
        3 => image::ExtendedColorType::Rgb8,
        _ => image::ExtendedColorType::Rgba8,
    };
    let mut out = Vec::new();
    let encoder = image::codecs::png::PngEncoder::new(&mut out);
    image::ImageEncoder::write_image(encoder, samples, width, height, color).expect("encode png");
    out
}

/// A grey sphere of radius `r` centred in a `size`×`size` 8-bit PNG, black background.
pub fn sphere_png(size: u32, r: f64) -> Vec<u8> {
    let c = (size as f64 - 1.0) / 2.0;
    let samples: Vec<u8> = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f64 - c, (i / size) as f64 - c);
            let d2 = (x * x + y * y) / (r * r);
            if d2 > 1.0 {
                0
            } else {
                (60.0 + 150.0 * (1.0 - d2).sqrt() + 20.0 * (x / 7.0).sin()) as u8
            }
        })
        .collect();
    png8(size, size, 1, &samples)
}

/// CRC-32 (IEEE) as PNG chunks use it.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// A PNG whose IHDR declares `width × height` (with a valid CRC) followed by a tiny IDAT.
pub fn png_with_header_size(width: u32, height: u32) -> Vec<u8> {
    let mut png = png8(4, 4, 1, &[7; 16]);
    // Signature (8) + length (4) + "IHDR" (4): width and height follow.
    png[16..20].copy_from_slice(&width.to_be_bytes());
    png[20..24].copy_from_slice(&height.to_be_bytes());
    let crc = crc32(&png[12..29]);
    png[29..33].copy_from_slice(&crc.to_be_bytes());
    png
}

/// A PNG built chunk by chunk: IHDR fields, extra chunks before IDAT, raw (unfiltered
/// scanlines with their filter bytes) stored uncompressed in zlib.
pub fn png_raw(
    width: u32,
    height: u32,
    depth: u8,
    color: u8,
    extra: &[(&[u8; 4], &[u8])],
    raw: &[u8],
) -> Vec<u8> {
    fn chunk(out: &mut Vec<u8>, kind: &[u8], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32(&body).to_be_bytes());
    }
    let adler = {
        let (mut a, mut b) = (1u32, 0u32);
        for &x in raw {
            a = (a + u32::from(x)) % 65521;
            b = (b + a) % 65521;
        }
        (b << 16) | a
    };
    let mut zlib = vec![0x78, 0x01];
    for (k, block) in raw.chunks(65535).enumerate() {
        let last = (k + 1) * 65535 >= raw.len();
        let n = block.len() as u16;
        zlib.push(u8::from(last));
        zlib.extend_from_slice(&n.to_le_bytes());
        zlib.extend_from_slice(&(!n).to_le_bytes());
        zlib.extend_from_slice(block);
    }
    zlib.extend_from_slice(&adler.to_be_bytes());
    let mut ihdr = width.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[depth, color, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    chunk(&mut png, b"IHDR", &ihdr);
    for (kind, data) in extra {
        chunk(&mut png, &kind[..], data);
    }
    chunk(&mut png, b"IDAT", &zlib);
    chunk(&mut png, b"IEND", &[]);
    png
}
