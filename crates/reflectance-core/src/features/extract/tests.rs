use super::*;
use crate::features::families::log::log_pixels;
use crate::features::families::{CAPTURE, CENTRE, DEPENDENCIES, DOMAIN, FAMILIES, LOG, RADIAL};
use crate::features::polar::UnwrapConfig;
use crate::features::sets::families_of;
use crate::features::{CAPTURE_NAMES, CENTRE_NAMES, DOMAIN_NAMES, FEATURE_COUNT, RADIAL_RINGS};
use crate::features::{Families, LOG_PIXEL_FLOOR, Preprocessing, default_names, named_set};
use crate::image::circle::Circle;
use ndarray::Array2;

/// The families the tests that name positions were written for (a family added later joins
/// [`Families::ALL`], not these).
fn the_six() -> Families {
    [&LOG, &RADIAL, &DEPENDENCIES, &CAPTURE, &CENTRE, &DOMAIN]
        .into_iter()
        .collect()
}

/// A 200² image of a textured sphere of radius 90, and its circle.
fn textured_sphere() -> (Array2<f64>, Circle) {
    let luminance = Array2::from_shape_fn((200, 200), |(y, x)| {
        let (dx, dy) = (x as f64 - 99.5, y as f64 - 99.5);
        let d2 = (dx * dx + dy * dy) / (90.0 * 90.0);
        if d2 > 1.0 {
            0.0
        } else {
            0.3 + 0.5 * (1.0 - d2).sqrt() + 0.1 * (dx / 5.0).sin() * (dy / 7.0).cos()
        }
    });
    let circle = Circle {
        cx: 99.5,
        cy: 99.5,
        r: 90.0,
    };
    (luminance, circle)
}

#[test]
fn names_are_canonical_and_unique() {
    let names = default_names();
    assert_eq!(names.len(), FEATURE_COUNT);
    let unique: std::collections::HashSet<_> = names.iter().collect();
    assert_eq!(unique.len(), FEATURE_COUNT);
    assert_eq!(names[0], "pix.mean");
    assert_eq!(names[7], "wav.s1.h.mean");
    assert_eq!(names[7 + 7 + 1], "wav.s1.v.var");
    assert_eq!(names[90], "wav.s4.d.p90");
    assert_eq!(names[91], "ratio.h.s1_s2");
    assert_eq!(names[99], "ratio.d.s3_s4");
    assert_eq!(names[100], "fft.b1.f0.pow");
    assert_eq!(names[115], "fft.b4.f135.pow");
    assert_eq!(names[116], "fft.lo.pow");
    for set in ["hand6", "hand2", "mean1"] {
        for n in named_set(set).unwrap() {
            assert!(names.contains(&n), "{n}");
        }
    }
    let extended = FeatureConfig::with_log_domain().names();
    assert_eq!(extended.len(), 2 * FEATURE_COUNT);
    assert_eq!(extended[FEATURE_COUNT], "log.pix.mean");
    for n in named_set("hand6+log").unwrap() {
        assert!(extended.contains(&n), "{n}");
    }
    let every = FeatureConfig::extended(the_six(), Preprocessing::default()).names();
    let block = FEATURE_COUNT + (RADIAL_RINGS - 1) * 14 + 12;
    assert_eq!(every.len(), 2 * block + 3 + 6 + 1);
    assert_eq!(every[2 * block..2 * block + 3], CAPTURE_NAMES);
    assert_eq!(every[2 * block + 3..2 * block + 9], CENTRE_NAMES);
    assert_eq!(every[2 * block + 9..], DOMAIN_NAMES);
    assert_eq!(every[..FEATURE_COUNT], names[..]);
    let last_pair = format!("r{}_r{RADIAL_RINGS}", RADIAL_RINGS - 1);
    assert_eq!(
        [&every[FEATURE_COUNT], &every[FEATURE_COUNT + 2]],
        ["radial.r1_r2.pix.mean", "radial.r1_r2.wav.s1.h.var"]
    );
    assert_eq!(
        every[block - 13],
        format!("radial.{last_pair}.wav.s4.d.var")
    );
    assert_eq!(
        [&every[block - 12], &every[block - 10], &every[block - 1]],
        ["dep.s1.hv", "dep.s1.vd", "dep.s4.vd"]
    );
    assert_eq!(every[block], "log.pix.mean");
    assert_eq!(
        every[2 * block - 13],
        format!("log.radial.{last_pair}.wav.s4.d.var")
    );
    assert_eq!(every[2 * block - 1], "log.dep.s4.vd");
    for set in ["hand6+log+radial", "hand6+log+radial+dep"] {
        for n in named_set(set).unwrap() {
            assert!(every.contains(&n), "{n}");
        }
    }
}

#[test]
fn families_of_names_and_specs() {
    let of_spec = |spec: &str| {
        let e = families_of(spec);
        (e.contains(&LOG), e.contains(&RADIAL))
    };
    assert_eq!(of_spec("hand6"), (false, false));
    assert_eq!(of_spec("all"), (false, false));
    assert_eq!(of_spec("hand6+log"), (true, false));
    assert_eq!(of_spec("hand6+log+radial"), (true, true));
    assert_eq!(
        of_spec("pix.mean, radial.r1_r2.wav.s1.v.var"),
        (false, true)
    );
    assert_eq!(of_spec("log.radial.r1_r2.pix.var"), (true, true));
    assert_eq!(of_spec("log.pix.mean,pix.p10"), (true, false));
    let centred = named_set("hand6+log+ctr").unwrap();
    assert_eq!(centred[..25], named_set("hand6+log").unwrap()[..]);
    assert_eq!(centred[25..], CENTRE_NAMES);
    let families = families_of("hand6+log+ctr");
    assert!(families.contains(&LOG) && families.contains(&CENTRE) && !families.contains(&CAPTURE));
    let config = FeatureConfig::extended(Families::ALL, Preprocessing::at_radius(80.0));
    let names = config.names();
    assert_eq!(
        Families::of_names(names.iter().map(String::as_str)),
        config.families
    );
}

/// An unwrapped image of `pattern(row, col)` times `gain(ring)` (rings of equal height,
/// innermost first).
fn by_ring(pattern: impl Fn(usize, usize) -> f64, gain: impl Fn(usize) -> f64) -> Array2<f64> {
    let u = UnwrapConfig::default();
    Array2::from_shape_fn((u.rows, u.cols), |(i, j)| {
        pattern(i, j) * gain(i * RADIAL_RINGS / u.rows)
    })
}

#[test]
fn radial_changes_compare_each_ring_of_the_annulus_with_the_one_inside_it() {
    let extractor =
        Extractor::new(FeatureConfig::extended(the_six(), Preprocessing::default())).unwrap();
    let names = extractor.config().names();
    let per = 2 + 3 * 4; // pixel mean and variance, 12 subband variances
    let radial = |unwrapped: Array2<f64>| {
        let values = extractor.features_of(&extractor.stages_of_unwrapped(unwrapped));
        let range = FEATURE_COUNT..FEATURE_COUNT + (RADIAL_RINGS - 1) * per;
        names[range.clone()]
            .iter()
            .cloned()
            .zip(values[range].iter().copied())
            .collect::<Vec<(String, f64)>>()
    };
    let value = |changes: &[(String, f64)], n: &str| {
        changes.iter().find(|(m, _)| m == n).map(|c| c.1).unwrap()
    };
    // Angular structure only, the same at every radius: nothing changes.
    let stripes = |_: usize, j: usize| 1.0 + 0.5 * (j as f64 * 0.7).sin() + 0.1 * (j % 5) as f64;
    for (name, value) in radial(by_ring(stripes, |_| 1.0)) {
        assert!(value.abs() < 1e-9, "{name} = {value}");
    }
    // Ring k (from 1) k × brighter: the mean grows by the ring-1 mean from ring to ring,
    // the variance by (k + 1)² / k².
    let u = by_ring(stripes, |k| (k + 1) as f64);
    let ring1_mean = u
        .slice(ndarray::s![..96 / RADIAL_RINGS, ..])
        .mean()
        .unwrap();
    let changes = radial(u);
    for k in 1..RADIAL_RINGS {
        let pair = format!("radial.r{k}_r{}.pix", k + 1);
        let mean = value(&changes, &format!("{pair}.mean"));
        assert!((mean - ring1_mean).abs() < 1e-12, "{pair}: {mean}");
        let var = value(&changes, &format!("{pair}.var"));
        let ratio = ((k + 1) * (k + 1)) as f64 / (k * k) as f64;
        assert!((var - ratio.log10()).abs() < 1e-12, "{pair}: {var}");
    }
    // Finer angular structure in the outermost ring: the finest vertical subband's
    // energy moves out, the coarsest's in.
    let outermost = RADIAL_RINGS - 1;
    let finer = |i: usize, j: usize| {
        let period = if i * RADIAL_RINGS / 96 == outermost {
            4.0
        } else {
            32.0
        };
        (std::f64::consts::TAU * j as f64 / period).sin()
    };
    let changes = radial(by_ring(finer, |_| 1.0));
    let last = format!("radial.r{outermost}_r{}.wav", outermost + 1);
    assert!(
        value(&changes, &format!("{last}.s1.v.var")) > 2.0,
        "{changes:?}"
    );
    assert!(
        value(&changes, &format!("{last}.s4.v.var")) < -0.5,
        "{changes:?}"
    );
}

#[test]
fn log_domain_features_are_the_features_of_the_log_image() {
    let img = ndarray::Array2::from_shape_fn((120, 130), |(y, x)| {
        let d = ((x as f64 - 64.0).powi(2) + (y as f64 - 59.5).powi(2)).sqrt();
        if d < 55.0 {
            0.2 + 0.5 * ((x as f64) * 0.3).sin().abs() + 0.001 * (y % 7) as f64
        } else {
            0.0
        }
    });
    let circle = Circle {
        cx: 64.0,
        cy: 59.5,
        r: 55.0,
    };
    let plain = Extractor::new(FeatureConfig::default()).unwrap();
    let extended = Extractor::new(FeatureConfig::with_log_domain()).unwrap();
    let values = extended.extract(img.view(), &circle, 0.8);
    assert_eq!(
        &values[..FEATURE_COUNT],
        plain.extract(img.view(), &circle, 0.8).as_slice()
    );
    let log = plain
        .unwrap(img.view(), &circle, 0.8)
        .mapv(|v| v.max(LOG_PIXEL_FLOOR).log10());
    let expected = plain.features_of(&plain.stages_of_unwrapped(log));
    // libm's log10 and ours differ by up to 2 ulp.
    for (got, want) in values[FEATURE_COUNT..].iter().zip(&expected) {
        assert!(
            (got - want).abs() <= 1e-12 * want.abs().max(1e-3),
            "{got} vs {want}"
        );
    }
}

#[test]
fn white_scales_the_unwrap_even_without_a_finite_reciprocal() {
    let img = Array2::from_shape_fn((128, 128), |(y, x)| 0.5 + 0.001 * (x + 3 * y) as f64);
    let circle = Circle {
        cx: 64.0,
        cy: 63.5,
        r: 60.0,
    };
    let extractor = Extractor::new(FeatureConfig::default()).unwrap();
    let unit = extractor.unwrap(img.view(), &circle, 1.0);
    let half = extractor.unwrap(img.view(), &circle, 0.5);
    assert!(
        unit.iter()
            .zip(&half)
            .all(|(u, h)| (2.0 * u - h).abs() < 1e-14)
    );
    // 1/1e-310 overflows; the cells are still the (finite) quotients.
    let faint = img.mapv(|v| v * 1e-300);
    let tiny = extractor.unwrap(faint.view(), &circle, 1e-310);
    assert!(
        unit.iter()
            .zip(&tiny)
            .all(|(u, t)| (u * 1e10 - t).abs() <= 1e-12 * t)
    );
}

#[test]
fn saturation_clips_the_white_normalized_unwrap() {
    let img = Array2::from_shape_fn((128, 128), |(y, x)| 0.02 * (x + y) as f64);
    let circle = Circle {
        cx: 64.0,
        cy: 63.5,
        r: 60.0,
    };
    let free = Extractor::new(FeatureConfig::default()).unwrap();
    let config = FeatureConfig {
        saturation: Some(1.25),
        ..FeatureConfig::default()
    };
    let clipped = Extractor::new(config).unwrap();
    let white = 2.0;
    let before = free.unwrap(img.view(), &circle, white);
    let after = clipped.unwrap(img.view(), &circle, white);
    assert!(before.iter().any(|&v| v > 1.5) && before.iter().any(|&v| v < 1.0));
    for (b, a) in before.iter().zip(&after) {
        assert_eq!(*a, b.min(1.25));
    }
    let features = |e: &Extractor| e.extract(img.view(), &circle, white);
    assert_ne!(features(&free), features(&clipped));
}

/// A rows × cols field of uniform noise around 0.5 (a stationary texture).
fn noise_field(rows: usize, cols: usize, seed: u64) -> Array2<f64> {
    let mut rng = crate::util::rng::Rng::new(seed);
    Array2::from_shape_fn((rows, cols), |_| 0.25 + 0.5 * rng.next_f64())
}

fn observed_where(rows: usize, cols: usize, seen: impl Fn(usize, usize) -> bool) -> Observed {
    let coverage = Array2::from_shape_fn((rows, cols), |(r, c)| f64::from(seen(r, c)));
    Observed::from_coverage(&coverage).unwrap()
}

#[test]
fn features_over_a_fully_observed_annulus_are_the_features() {
    let config = (FeatureConfig::default())
        .with(&LOG)
        .with(&RADIAL)
        .with(&DEPENDENCIES);
    let extractor = Extractor::new(config).unwrap();
    let (rows, cols) = (config.unwrap.rows, config.unwrap.cols);
    let unwrapped = noise_field(rows, cols, 3);
    let everything = observed_where(rows, cols, |_, _| true);
    let over = extractor.features_over(&unwrapped, &everything);
    let mut want = extractor.features_of(&extractor.stages_of_unwrapped(unwrapped.clone()));
    let log = extractor.stages_of_unwrapped(log_pixels(&unwrapped));
    want.extend(extractor.features_of(&log));
    assert_eq!(over.len(), want.len());
    for (k, (a, b)) in over.iter().zip(&want).enumerate() {
        assert_eq!(a.to_bits(), b.to_bits(), "feature {k}: {a} against {b}");
    }
}

#[test]
fn features_over_half_a_texture_estimate_the_whole_textures_statistics() {
    let extractor = Extractor::new(FeatureConfig::default()).unwrap();
    let config = extractor.config();
    let (rows, cols) = (config.unwrap.rows, config.unwrap.cols);
    let names = extractor.layout.names();
    let at = |name: &str| names.iter().position(|n| n == name).unwrap();
    let unwrapped = noise_field(rows, cols, 5);
    let whole = extractor.features_of(&extractor.stages_of_unwrapped(unwrapped.clone()));
    // Half the angles seen, and what fills the other half must not matter.
    let half = observed_where(rows, cols, |_, c| c < cols / 2);
    let mut hidden = unwrapped.clone();
    for ((_, c), v) in hidden.indexed_iter_mut() {
        if c >= cols / 2 {
            *v = 40.0;
        }
    }
    let over = extractor.features_over(&hidden, &half);
    for name in [
        "pix.mean",
        "pix.var",
        "pix.p50",
        "wav.s1.h.var",
        "wav.s2.v.var",
        "wav.s3.d.var",
    ] {
        let (a, b) = (over[at(name)], whole[at(name)]);
        assert!((a - b).abs() < 0.05, "{name}: {a} over half, {b} whole");
    }
    // The band powers still sum to the (observed) variance.
    let layout = &extractor.layout.block;
    let total: f64 = over[layout.band_powers()]
        .iter()
        .map(|p| 10f64.powf(*p))
        .sum();
    let var = 10f64.powf(over[at("pix.var")]);
    assert!((total / var - 1.0).abs() < 1e-6, "{total} against {var}");
}

#[test]
fn subsets_are_bit_identical_to_the_full_extraction() {
    let (luminance, circle) = textured_sphere();
    let extractor = Extractor::new(FeatureConfig::default()).unwrap();
    assert_eq!(extractor.feature_count(), FEATURE_COUNT);
    let full = extractor.extract(luminance.view(), &circle, 0.9);
    let names = default_names();
    let index = |n: &str| names.iter().position(|m| m == n).unwrap();
    let hand6: Vec<usize> = named_set("hand6")
        .unwrap()
        .iter()
        .map(|n| index(n))
        .collect();
    let subsets: Vec<Vec<usize>> = vec![
        hand6,
        vec![index("ratio.d.s3_s4")],
        vec![index("fft.b2.f45.pow"), index("wav.s4.h.p90")],
        vec![index("pix.p50"), index("wav.s1.v.skew")],
        vec![
            index("pix.p90"),
            index("wav.s2.d.p10"),
            index("wav.s2.d.p50"),
        ],
        (0..FEATURE_COUNT).collect(),
        vec![],
    ];
    let extended = Extractor::new(FeatureConfig::extended(
        the_six(),
        Preprocessing::at_radius(60.0),
    ))
    .unwrap();
    let extended_full = extended.extract(luminance.view(), &circle, 0.9);
    let block = FEATURE_COUNT + (RADIAL_RINGS - 1) * 14 + 12;
    let count = 2 * block + 3 + 6 + 1;
    assert_eq!(extended.feature_count(), count);
    assert_eq!(extended_full.len(), count);
    let extended_subsets = [
        vec![3, block + 1, block + 99, 2 * block - 1],
        // dep.s3.vd alone (three pyramid levels), dep.s1.hv and log.dep.s4.hd
        vec![block - 4],
        vec![block - 12, 2 * block - 2],
        // radial.r1_r2.pix.var, radial.r1_r2.wav.s2.v.var; two of the log-domain block
        vec![FEATURE_COUNT + 1, FEATURE_COUNT + 6],
        vec![block + FEATURE_COUNT, block + FEATURE_COUNT + 13],
        // The capture measurements, alone and with a block feature.
        vec![2 * block + 1],
        vec![5, 2 * block],
        vec![2 * block + 2],
        // The centre features, alone, with a capture measurement and with a block feature.
        vec![2 * block + 4],
        vec![2 * block + 2, 2 * block + 3],
        vec![7, count - 2],
        // The domain measurement, alone and with a centre feature.
        vec![count - 1],
        vec![count - 2, count - 1],
        (0..count).collect::<Vec<_>>(),
    ];
    for wanted in extended_subsets {
        let part = extended.extract_subset(luminance.view(), &circle, 0.9, &wanted);
        assert_eq!(part.len(), count);
        for &i in &wanted {
            assert_eq!(
                part[i].to_bits(),
                extended_full[i].to_bits(),
                "extended {i}"
            );
        }
    }
    for wanted in subsets {
        let part = extractor.extract_subset(luminance.view(), &circle, 0.9, &wanted);
        assert_eq!(part.len(), FEATURE_COUNT);
        for (i, (a, b)) in part.iter().zip(&full).enumerate() {
            if wanted.contains(&i) {
                assert_eq!(a.to_bits(), b.to_bits(), "{}", names[i]);
            }
        }
    }
}

#[test]
fn every_familys_features_alone_are_bit_identical_to_the_full_extraction() {
    let (luminance, circle) = textured_sphere();
    let config = FeatureConfig::extended(Families::ALL, Preprocessing::at_radius(60.0));
    let extractor = Extractor::new(config).unwrap();
    let full = extractor.extract(luminance.view(), &circle, 0.9);
    let layout = config.layout();
    assert_eq!(full.len(), layout.count());
    for family in FAMILIES {
        let wanted: Vec<usize> = layout.family(family).collect();
        assert!(!wanted.is_empty(), "{}", family.key);
        let part = extractor.extract_subset(luminance.view(), &circle, 0.9, &wanted);
        for &i in &wanted {
            assert_eq!(part[i].to_bits(), full[i].to_bits(), "{} {i}", family.key);
        }
    }
}

#[test]
fn orientation_dependencies_ignore_the_brightness_of_the_image() {
    let config = FeatureConfig::default().with(&DEPENDENCIES);
    let extractor = Extractor::new(config).unwrap();
    let u = config.unwrap;
    let image = Array2::from_shape_fn((u.rows, u.cols), |(i, j)| {
        1.0 + (0.3 * i as f64).sin() * (0.2 * j as f64).cos() + ((i * j) % 7) as f64 / 7.0
    });
    let deps = |scale: f64| {
        let values =
            extractor.features_of(&extractor.stages_of_unwrapped(image.mapv(|v| v * scale)));
        values[FEATURE_COUNT..].to_vec()
    };
    let (one, three) = (deps(1.0), deps(3.0));
    assert_eq!(one.len(), 12);
    assert!(one.iter().all(|c| (-1.0..=1.0).contains(c)));
    assert!(one.iter().any(|c| c.abs() > 0.01), "{one:?}");
    for (a, b) in one.iter().zip(&three) {
        assert!((a - b).abs() < 1e-9, "{a} {b}");
    }
}

#[test]
fn a_model_file_from_before_ctr_cos_extracts_its_own_five_centre_values() {
    let config = FeatureConfig::default().with(&CENTRE).with(&DOMAIN);
    let mut json = serde_json::to_value(config).unwrap();
    assert_eq!(json["centre_cos"], true);
    json.as_object_mut().unwrap().remove("centre_cos");
    let old: FeatureConfig = serde_json::from_value(json).unwrap();
    let (names, old_names) = (config.names(), old.names());
    assert_eq!(
        names[FEATURE_COUNT..],
        [
            "ctr.mean",
            "ctr.core",
            "ctr.p10",
            "ctr.p50",
            "ctr.p90",
            "ctr.cos",
            "dom.outline"
        ]
    );
    let without_cos: Vec<&String> = names.iter().filter(|n| *n != "ctr.cos").collect();
    assert_eq!(old_names.iter().collect::<Vec<_>>(), without_cos);
    let circle = Circle {
        cx: 60.0,
        cy: 60.0,
        r: 50.0,
    };
    let image = Array2::from_shape_fn((121, 121), |(y, x)| {
        0.2 + 0.1 * ((x as f64 * 0.3).sin() + (y as f64 * 0.2).cos()).abs()
    });
    let new_row = Extractor::new(config)
        .unwrap()
        .extract(image.view(), &circle, 0.5);
    let old_row = Extractor::new(old)
        .unwrap()
        .extract(image.view(), &circle, 0.5);
    assert_eq!(old_row.len(), old_names.len());
    let cos = names.iter().position(|n| n == "ctr.cos").unwrap();
    let mut expected = new_row.clone();
    expected.remove(cos);
    assert_eq!(old_row, expected);
}

#[test]
fn config_validation() {
    let ok = FeatureConfig::default();
    assert_eq!(ok.validate(), Ok(()));
    let mut bad = ok;
    bad.unwrap.cols = 440;
    assert!(matches!(
        bad.validate(),
        Err(ConfigError::WidthNotDivisible { .. })
    ));
    let mut bad = ok;
    bad.unwrap.rows = 64;
    assert!(matches!(
        bad.validate(),
        Err(ConfigError::HeightTooSmall { level: 3, .. })
    ));
    let mut bad = ok;
    bad.unwrap.inner = 0.95;
    assert!(matches!(
        bad.validate(),
        Err(ConfigError::BadAnnulus { .. })
    ));
    for saturation in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let bad = FeatureConfig {
            saturation: Some(saturation),
            ..ok
        };
        assert!(matches!(bad.validate(), Err(ConfigError::BadSaturation(_))));
    }
}

/// A sharp (area-sampled) shaded disc of radius `r` centred in a square image 2.4 r across.
fn sharp_disc(r: f64) -> (Array2<f64>, Circle) {
    let side = (2.4 * r) as usize;
    let c = side as f64 / 2.0 - 0.3;
    let offsets = [-0.375, -0.125, 0.125, 0.375];
    let image = Array2::from_shape_fn((side, side), |(y, x)| {
        let inside = offsets
            .iter()
            .flat_map(|dy| offsets.iter().map(move |dx| (dx, dy)))
            .filter(|(dx, dy)| (x as f64 + **dx - c).hypot(y as f64 + **dy - c) <= r)
            .count() as f64
            / 16.0;
        inside * (0.4 + 0.3 * x as f64 / side as f64) + (1.0 - inside) * 0.1
    });
    (image, Circle { cx: c, cy: c, r })
}

#[test]
fn the_rim_blur_at_the_working_radius_reads_a_large_sharp_ball_as_a_small_one() {
    let blur_of = |blur_at_working_radius: bool, r: f64| {
        let preprocessing = Preprocessing {
            working_radius: Some(64.0),
            blur_at_working_radius,
            ..Preprocessing::default()
        };
        let config = FeatureConfig::extended(Families::NONE.with(&CAPTURE), preprocessing);
        let (image, circle) = sharp_disc(r);
        let row = Extractor::new(config)
            .unwrap()
            .extract(image.view(), &circle, 0.7);
        row[config.names().iter().position(|n| n == "cap.blur").unwrap()]
    };
    // At the working radius itself both read the same sharp rim.
    assert_eq!(blur_of(false, 64.0), blur_of(true, 64.0));
    let small = blur_of(true, 64.0);
    // Four times as large and as sharp: as given, its rim reads far sharper per radius than
    // any ball of 64 px can (a model trained on them never saw it); at the working radius,
    // about as the small ball's (the reduction's own blur aside).
    let (given, seen) = (blur_of(false, 256.0), blur_of(true, 256.0));
    assert!(given < small - 0.3, "as given {given}, small {small}");
    assert!(
        (seen - small).abs() < 0.3,
        "at the working radius {seen}, small {small}"
    );
}

#[test]
fn a_model_file_records_the_rim_blur_at_the_working_radius_only_when_on() {
    let off = FeatureConfig::extended(
        Families::NONE.with(&CAPTURE),
        Preprocessing::at_radius(64.0),
    );
    let json = serde_json::to_value(off).unwrap();
    assert!(json.get("blur_at_working_radius").is_none(), "{json}");
    let on = FeatureConfig {
        blur_at_working_radius: true,
        ..off
    };
    let json = serde_json::to_value(on).unwrap();
    assert_eq!(json["blur_at_working_radius"], true);
    assert_eq!(serde_json::from_value::<FeatureConfig>(json).unwrap(), on);
    assert!(on.preprocessing().blur_at_working_radius);
}
