//! Bad input never panics: every corruption is a typed error with a clear message.

use crate::common;

use common::*;
use reflectance_core::decode::{DecodeError, DecodeOptions, Limits, decode, pfm, rgbe};

fn err(bytes: &[u8]) -> DecodeError {
    decode(bytes, &DecodeOptions::default()).expect_err("must be refused")
}

#[test]
fn truncated_files_of_every_format() {
    let png = sphere_png(64, 20.0);
    for cut in [8, 20, 40, png.len() / 2, png.len() - 13] {
        let e = err(&png[..cut]);
        assert!(
            matches!(e, DecodeError::Corrupt { .. }),
            "png cut at {cut}: {e:?}"
        );
    }
    let jpeg = {
        let mut out = Vec::new();
        let enc = image::codecs::jpeg::JpegEncoder::new(&mut out);
        image::ImageEncoder::write_image(
            enc,
            &[128u8; 64 * 64],
            64,
            64,
            image::ExtendedColorType::L8,
        )
        .unwrap();
        out
    };
    assert!(matches!(
        err(&jpeg[..jpeg.len() / 3]),
        DecodeError::Corrupt { .. }
    ));
    let tiff = {
        let mut out = std::io::Cursor::new(Vec::new());
        let enc = image::codecs::tiff::TiffEncoder::new(&mut out);
        image::ImageEncoder::write_image(
            enc,
            &[9u8; 32 * 32],
            32,
            32,
            image::ExtendedColorType::L8,
        )
        .unwrap();
        out.into_inner()
    };
    assert!(decode(&tiff, &DecodeOptions::default()).is_ok());
    assert!(matches!(
        err(&tiff[..tiff.len() / 2]),
        DecodeError::Corrupt { .. }
    ));
    let hdr = rgbe::write_flat(16, 16, &[1.0; 256]);
    assert!(matches!(
        err(&hdr[..hdr.len() - 100]),
        DecodeError::Corrupt { .. }
    ));
    let pfm = pfm::encode_gray(16, 16, &[1.0; 256]);
    assert!(matches!(
        err(&pfm[..pfm.len() - 4]),
        DecodeError::Corrupt { .. }
    ));
    let exr = [0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0, b'c', b'h'];
    assert!(matches!(
        err(&exr),
        DecodeError::Corrupt { .. } | DecodeError::Unsupported { .. }
    ));
}

#[test]
fn corrupt_bytes_inside_a_png() {
    let mut png = sphere_png(64, 20.0);
    let middle = png.len() / 2;
    png[middle..middle + 16].iter_mut().for_each(|b| *b ^= 0x5a);
    assert!(matches!(err(&png), DecodeError::Corrupt { .. }));
}

#[test]
fn giant_and_empty_headers_are_refused_before_decoding() {
    for (w, h) in [(100_000, 100_000), (1_000_000, 1), (30_000, 30_000)] {
        let e = err(&png_with_header_size(w, h));
        assert!(
            matches!(
                e,
                DecodeError::TooLarge { .. } | DecodeError::LimitExceeded(_)
            ),
            "{w}×{h}: {e:?}"
        );
        // Either way the message says what the limits are.
        assert!(e.to_string().contains("20000×20000"), "{e}");
    }
    assert!(matches!(
        err(&png_with_header_size(0, 10)),
        DecodeError::Empty { .. } | DecodeError::Corrupt { .. }
    ));
    let huge_pfm = b"PF\n100000 100000\n-1\n";
    assert!(matches!(err(huge_pfm), DecodeError::TooLarge { .. }));
    let huge_hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n";
    assert!(matches!(err(huge_hdr), DecodeError::TooLarge { .. }));
    // Configurable limits.
    let small = DecodeOptions {
        limits: Limits {
            max_width: 32,
            max_height: 32,
            max_pixels: 1024,
        },
        ..Default::default()
    };
    let e = decode(&sphere_png(64, 20.0), &small).unwrap_err();
    assert!(
        matches!(
            e,
            DecodeError::TooLarge { .. } | DecodeError::LimitExceeded(_)
        ),
        "{e:?}"
    );
}

#[test]
fn non_finite_and_negative_float_pixels() {
    let cases: [(&[f32], &str); 3] = [
        (&[f32::NAN, 1.0], "non-finite"),
        (&[f32::INFINITY, 1.0], "non-finite"),
        (&[-1.0, 1.0], "negative"),
    ];
    for (values, word) in cases {
        let e = err(&pfm::encode_gray(2, 1, values));
        assert!(e.to_string().contains(word), "{e}");
    }
}

#[test]
fn sixteen_bit_and_palette_pngs_decode_exactly() {
    // 16-bit grey: code 65535 is 1.0 in every encoding; palette images expand to RGB.
    let mut out = Vec::new();
    let enc = image::codecs::png::PngEncoder::new(&mut out);
    let samples: Vec<u8> = [0u16, 65535, 32768, 1]
        .iter()
        .flat_map(|v| v.to_ne_bytes())
        .collect();
    image::ImageEncoder::write_image(enc, &samples, 2, 2, image::ExtendedColorType::L16).unwrap();
    let img = decode(&out, &DecodeOptions::default()).unwrap();
    assert_eq!(img.luminance[[0, 1]], 1.0);
    assert_eq!(img.luminance[[0, 0]], 0.0);
    let linear = decode(
        &out,
        &DecodeOptions {
            encoding: Some(reflectance_core::decode::Encoding::Linear),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(linear.luminance[[1, 0]], 32768.0 / 65535.0);
    // Palette PNG (colour type 3) with entries black, white, mid-grey: expands to its RGB.
    let palette = palette_png(
        &[[0, 0, 0], [255, 255, 255], [128, 128, 128]],
        &[0, 1, 2, 1],
    );
    let img = decode(
        &palette,
        &DecodeOptions {
            encoding: Some(reflectance_core::decode::Encoding::Linear),
            ..Default::default()
        },
    )
    .unwrap();
    let expected = [0.0, 1.0, 128.0 / 255.0, 1.0];
    for (got, want) in img.luminance.iter().zip(expected) {
        assert!((got - want).abs() < 1e-12, "{got} vs {want}");
    }
}

/// A 2×2, 8-bit palette PNG.
fn palette_png(entries: &[[u8; 3]], indices: &[u8; 4]) -> Vec<u8> {
    let raw = [0, indices[0], indices[1], 0, indices[2], indices[3]];
    png_raw(2, 2, 8, 3, &[(b"PLTE", &entries.concat())], &raw)
}

#[test]
fn alpha_channel_becomes_a_mask() {
    let samples: Vec<u8> = (0..16)
        .flat_map(|i| [200, if i % 2 == 0 { 255 } else { 0 }])
        .collect();
    let img = decode(&png8(4, 4, 2, &samples), &DecodeOptions::default()).unwrap();
    let mask = img.alpha_mask.expect("mask");
    assert!(mask[[0, 0]] && !mask[[0, 1]]);
    let opaque: Vec<u8> = (0..16).flat_map(|_| [200, 255]).collect();
    assert!(
        decode(&png8(4, 4, 2, &opaque), &DecodeOptions::default())
            .unwrap()
            .alpha_mask
            .is_none()
    );
}

#[test]
fn exif_orientation_is_applied() {
    // A 2×1 JPEG-free check: PNG eXIf chunk with orientation 6 (rotate 90° clockwise).
    let png = png8(2, 1, 1, &[0, 255]);
    let exif: Vec<u8> = {
        let mut e = b"MM\0\x2a\0\0\0\x08\0\x01".to_vec();
        e.extend_from_slice(&[0x01, 0x12, 0, 3, 0, 0, 0, 1, 0, 6, 0, 0]);
        e.extend_from_slice(&[0, 0, 0, 0]);
        e
    };
    let mut chunk = (exif.len() as u32).to_be_bytes().to_vec();
    chunk.extend_from_slice(b"eXIf");
    chunk.extend_from_slice(&exif);
    let crc = crc32(&chunk[4..]);
    chunk.extend_from_slice(&crc.to_be_bytes());
    // Insert after IHDR (8 + 25 bytes).
    let mut with_exif = png[..33].to_vec();
    with_exif.extend_from_slice(&chunk);
    with_exif.extend_from_slice(&png[33..]);
    let img = decode(&with_exif, &DecodeOptions::default()).unwrap();
    assert_eq!(img.luminance.dim(), (2, 1), "rotated to 1 wide, 2 high");
    assert_eq!(img.luminance[[0, 0]], 0.0);
    assert_eq!(img.luminance[[1, 0]], 1.0);
}
