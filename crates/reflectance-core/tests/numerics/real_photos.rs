//! Automatic sphere detection on real photographs: the development sets in
//! `../shared/data/photos/dev/` (31 photographs from 9 public repositories, mostly mirror
//! balls) and `dev2/` (8 balls of other materials from 5 more), the true circles fitted to
//! the rim and checked by eye (`manifest.csv`, `PROVENANCE.md`). Found
//! means the circle detection chose is within 4 % of the true radius, in centre and in
//! radius; wrong, another circle; refused, none.
//!
//! `cargo test --release --test numerics real_photographs -- --nocapture --test-threads 1`
//! prints the table per kind (a photo counts under each of its tags), per source and per set, the
//! time per photo (decoding and detection), and a line per photo (with where the true
//! circle is among the alternatives offered); `REFLECTANCE_REAL_PHOTOS_VERBOSE=1` also
//! lists the first five alternatives. `REFLECTANCE_REAL_PHOTOS_HOLDOUT=a,b` names sources
//! (parts of their repository names) held out while tuning: they are left out of the lines
//! and tables, and their figure is printed apart; `REFLECTANCE_REAL_PHOTOS_ONLY=name` runs the
//! photos whose file name contains it (no floor then); `REFLECTANCE_DETECT_LONG_SIDE=N` detects
//! on the photograph area-reduced to a long side of N px (no floor then either).

use reflectance_core::decode::{DecodeOptions, LinearImage, Photo as Decoded};
use reflectance_core::locate::{self, GeometryError};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

/// The development sets: `dev` (mirror balls mostly, the detector tuned on it) and `dev2`
/// (balls of other materials, given for issue 68; detection was never tuned on it).
const SETS: [&str; 2] = ["dev", "dev2"];

fn set_dir(set: &str) -> PathBuf {
    crate::common::shared().join("data/photos").join(set)
}

/// The fields of one CSV line (quoted fields may hold commas and doubled quotes).
fn fields(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '"' if quoted && chars.peek() == Some(&'"') => {
                chars.next();
                out.last_mut().unwrap().push('"');
            }
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(String::new()),
            _ => out.last_mut().unwrap().push(c),
        }
    }
    out
}

struct Photo {
    set: String,
    path: String,
    kind: String,
    source: String,
    cx: f64,
    cy: f64,
    r: f64,
}

impl Photo {
    /// Found when the circle (cx, cy, r) is within 4 % of the true radius, in centre and in
    /// radius; else wrong.
    fn outcome_of(&self, cx: f64, cy: f64, r: f64) -> Outcome {
        let within = 0.04 * self.r;
        if (cx - self.cx).hypot(cy - self.cy) <= within && (r - self.r).abs() <= within {
            Outcome::Found
        } else {
            Outcome::Wrong
        }
    }
}

fn manifest(set: &str) -> Vec<Photo> {
    let path = set_dir(set).join("manifest.csv");
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (../shared is required)", path.display()));
    let mut lines = text.lines();
    let header = fields(lines.next().unwrap());
    let column = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (p, k, x, y, r, s) = (
        column("path"),
        column("kind"),
        column("cx"),
        column("cy"),
        column("r"),
        column("source_repo"),
    );
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|line| {
            let f = fields(line);
            Photo {
                set: set.to_string(),
                path: f[p].clone(),
                kind: f[k].clone(),
                source: f[s].clone(),
                cx: f[x].parse().unwrap(),
                cy: f[y].parse().unwrap(),
                r: f[r].parse().unwrap(),
            }
        })
        .collect()
}

/// The photograph as a located request reads it: decoded whole at full size by
/// `decode::Photo`, whatever decoder that uses.
fn as_located(photo: &Photo, options: &DecodeOptions) -> LinearImage {
    const _: () = assert!(reflectance_core::analysis::LOCATING_SIDE == usize::MAX);
    let bytes = std::fs::read(set_dir(&photo.set).join(&photo.path)).unwrap();
    let decoded = Decoded::open(&bytes, options).unwrap();
    decoded.whole(1).unwrap().image.into_owned()
}

#[derive(Clone, Copy, PartialEq)]
enum Outcome {
    Found,
    Wrong,
    Refused,
}

/// Found, wrong, refused.
type Tally = [usize; 3];

fn add(tallies: &mut BTreeMap<String, Tally>, key: &str, outcome: Outcome) {
    tallies.entry(key.to_string()).or_default()[outcome as usize] += 1;
}

fn print_table(title: &str, tallies: &BTreeMap<String, Tally>) {
    eprintln!("| {title} | found | wrong | refused |\n|---|---|---|---|");
    for (key, [found, wrong, refused]) in tallies {
        let n = found + wrong + refused;
        eprintln!("| {key} | {found} / {n} | {wrong} | {refused} |");
    }
}

/// The found count measured on each set (docs/accuracy.md: `dev` 25, 21 before an outline
/// could be elongated by up to 3 % any way, as an unevenly rescaled crop draws it; `dev2` 7,
/// 6 before a printed disc gave way to the ball around it), less one for a photo on the edge
/// of 4 %: detection must not fall below it.
const FOUND_FLOOR: [(&str, usize); 2] = [("dev", 24), ("dev2", 6)];

#[test]
#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data/photos/dev beside the repository"
)]
fn real_photographs() {
    let photos: Vec<Photo> = SETS.iter().flat_map(|set| manifest(set)).collect();
    let options = DecodeOptions {
        encoding: None,
        colour: false,
        limits: Default::default(),
    };
    let mut per_kind: BTreeMap<String, Tally> = BTreeMap::new();
    let mut per_source: BTreeMap<String, Tally> = BTreeMap::new();
    let mut per_set: BTreeMap<String, Tally> = BTreeMap::new();
    let mut total: Tally = [0; 3];
    let mut held_out: Tally = [0; 3];
    let holdout: Vec<String> = std::env::var("REFLECTANCE_REAL_PHOTOS_HOLDOUT")
        .unwrap_or_default()
        .split(',')
        .filter(|s| !s.is_empty())
        .map(str::to_string)
        .collect();
    let started = Instant::now();
    let only = std::env::var("REFLECTANCE_REAL_PHOTOS_ONLY").unwrap_or_default();
    for photo in photos.iter().filter(|p| p.path.contains(only.as_str())) {
        let t = Instant::now();
        let image = as_located(photo, &options);
        // What `classify` does without a circle: the alpha channel, else detection.
        let (found, ranked) = match &image.alpha_mask {
            Some(alpha) => (
                locate::fit_mask(alpha.view(), locate::Method::Alpha),
                Vec::new(),
            ),
            None => crate::detection::detect_as_received(image.luminance.view()),
        };
        let seconds = t.elapsed().as_secs_f64();
        let outcome = match &found {
            Ok(g) => photo.outcome_of(g.cx, g.cy, g.r),
            Err(_) => Outcome::Refused,
        };
        let said = match &found {
            Ok(g) => format!(
                "({:.1}, {:.1}, r {:.1}) confidence {:.2}",
                g.cx,
                g.cy,
                g.r,
                g.confidence.unwrap_or(1.0)
            ),
            Err(GeometryError::DetectionFailed { reason }) => reason.clone(),
            Err(e) => e.to_string(),
        };
        total[outcome as usize] += 1;
        add(&mut per_set, &photo.set, outcome);
        if holdout.iter().any(|h| photo.source.contains(h.as_str())) {
            held_out[outcome as usize] += 1;
            continue;
        }
        let mark = ["found", "WRONG", "refused"][outcome as usize];
        // Where the true circle is among the alternatives offered (confidence ≥ 0.3).
        let close = |g: &locate::Geometry| photo.outcome_of(g.cx, g.cy, g.r) == Outcome::Found;
        let offered = match ranked.iter().position(close) {
            Some(k) => format!(
                "; the true circle is offered {} at {:.2}",
                k + 1,
                ranked[k].confidence.unwrap_or(0.0)
            ),
            None => "; the true circle is not offered".into(),
        };
        eprintln!(
            "{mark:7} {:42} {:>5.2} s  truth ({:.1}, {:.1}, r {:.1}): {said}{offered}",
            photo.path, seconds, photo.cx, photo.cy, photo.r
        );
        if std::env::var_os("REFLECTANCE_REAL_PHOTOS_VERBOSE").is_some() {
            for g in ranked.iter().take(5) {
                eprintln!(
                    "        offered ({:.1}, {:.1}, r {:.1}) at {:.2}",
                    g.cx,
                    g.cy,
                    g.r,
                    g.confidence.unwrap_or(0.0)
                );
            }
        }
        for tag in photo.kind.split('+') {
            add(&mut per_kind, &format!("{}: {tag}", photo.set), outcome);
        }
        add(
            &mut per_source,
            &format!("{}: {}", photo.set, photo.source),
            outcome,
        );
    }
    let elapsed = started.elapsed().as_secs_f64();
    print_table("kind (each tag)", &per_kind);
    print_table("source", &per_source);
    print_table("set", &per_set);
    if !holdout.is_empty() {
        let [found, wrong, refused] = held_out;
        eprintln!(
            "held out ({}): found {found}, wrong {wrong}, refused {refused}",
            holdout.join(", ")
        );
    }
    let [found, wrong, refused] = total;
    eprintln!(
        "all: found {found} / {}, wrong {wrong}, refused {refused}; {:.2} s per photo",
        photos.len(),
        elapsed / photos.len() as f64
    );
    if !only.is_empty() || std::env::var_os("REFLECTANCE_DETECT_LONG_SIDE").is_some() {
        return;
    }
    for (set, floor) in FOUND_FLOOR {
        let [found, wrong, refused] = per_set.get(set).copied().unwrap_or_default();
        assert!(
            found >= floor,
            "{set}: found {found} of {}, below the floor of {floor}",
            found + wrong + refused
        );
    }
}

/// The thresholds [`locate::chosen_by`] is measured with, leaving a source out: every
/// combination of these, each from the loosest to the strictest.
const CONFIDENCES: [f64; 6] = [0.40, 0.45, 0.50, 0.55, 0.60, 0.65];
const ALONE: [f64; 6] = [0.30, 0.35, 0.40, 0.45, 0.50, f64::INFINITY];
const RUNNER_UP_SHARES: [f64; 4] = [0.9, 0.75, 0.6, 0.5];

/// The outcome of `acceptance` on one photograph's ranked candidates.
fn judged(photo: &Photo, ranked: &[locate::Found], acceptance: &locate::Acceptance) -> Outcome {
    match locate::chosen_by(ranked, acceptance) {
        Ok(f) => photo.outcome_of(f.circle.cx, f.circle.cy, f.circle.r),
        Err(_) => Outcome::Refused,
    }
}

/// Found less wrong (a wrong circle costs what a found one gains).
fn score(tally: &Tally) -> i64 {
    tally[0] as i64 - tally[1] as i64
}

/// The found count of the acceptance thresholds chosen without each source (docs/accuracy.md:
/// 31 of 39), less one: the leave-one-source-out figure must not fall below it.
const LEFT_OUT_FLOOR: usize = 30;

/// Leave one source out (issue 67): for each source of both development sets, the acceptance
/// thresholds that score best on the other sources (found less wrong; ties to the strictest),
/// judged on that source. Only the acceptance rule is chosen so; the candidate search (its
/// vote, fits, ball-likeness and soft rims) was tuned on every source of `dev`, and what it
/// finds is the same whichever source is left out. `cargo test --release --test numerics
/// acceptance_left_one_source_out -- --nocapture` prints the table per source.
#[test]
#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data/photos/dev beside the repository"
)]
fn acceptance_left_one_source_out() {
    let options = DecodeOptions {
        encoding: None,
        colour: false,
        limits: Default::default(),
    };
    let photos: Vec<(Photo, Vec<locate::Found>)> = SETS
        .iter()
        .flat_map(|set| manifest(set))
        .map(|photo| {
            let image = as_located(&photo, &options);
            let ranked = locate::candidates(image.luminance.view()).unwrap_or_default();
            (photo, ranked)
        })
        .collect();
    let grid: Vec<locate::Acceptance> = CONFIDENCES
        .iter()
        .flat_map(|&confidence| {
            ALONE.iter().flat_map(move |&alone| {
                RUNNER_UP_SHARES
                    .iter()
                    .map(move |&runner_up_share| locate::Acceptance {
                        confidence,
                        alone,
                        runner_up_share,
                    })
            })
        })
        .collect();
    let sources: std::collections::BTreeSet<&str> =
        photos.iter().map(|(p, _)| p.source.as_str()).collect();
    let tally = |acceptance: &locate::Acceptance, keep: &dyn Fn(&Photo) -> bool| {
        let mut t: Tally = [0; 3];
        for (photo, ranked) in photos.iter().filter(|(p, _)| keep(p)) {
            t[judged(photo, ranked, acceptance) as usize] += 1;
        }
        t
    };
    let mut left_out: BTreeMap<String, Tally> = BTreeMap::new();
    let mut shipped: BTreeMap<String, Tally> = BTreeMap::new();
    let (mut all_left_out, mut all_shipped): (Tally, Tally) = ([0; 3], [0; 3]);
    for source in sources {
        let others = |p: &Photo| p.source != source;
        let own = |p: &Photo| p.source == source;
        // Ties to the strictest: the grid runs from the loosest, so the last best wins.
        let best = grid
            .iter()
            .max_by_key(|a| score(&tally(a, &others)))
            .copied()
            .unwrap();
        let best = grid
            .iter()
            .rev()
            .find(|a| score(&tally(a, &others)) == score(&tally(&best, &others)))
            .copied()
            .unwrap_or(best);
        let set = photos
            .iter()
            .find(|(p, _)| own(p))
            .map(|(p, _)| p.set.clone())
            .unwrap_or_default();
        let key = format!("{set}: {source}");
        let held = tally(&best, &own);
        let now = tally(&locate::ACCEPTANCE, &own);
        eprintln!(
            "{key}: chosen without it {:.2} / {:.2} / {:.2}",
            best.confidence, best.alone, best.runner_up_share
        );
        for k in 0..3 {
            all_left_out[k] += held[k];
            all_shipped[k] += now[k];
        }
        left_out.insert(key.clone(), held);
        shipped.insert(key, now);
    }
    print_table("source, thresholds chosen without it", &left_out);
    print_table("source, the service's thresholds", &shipped);
    eprintln!(
        "left one source out: found {} / wrong {} / refused {}; the service's thresholds: {} / {} / {}",
        all_left_out[0],
        all_left_out[1],
        all_left_out[2],
        all_shipped[0],
        all_shipped[1],
        all_shipped[2]
    );
    assert!(
        all_left_out[0] >= LEFT_OUT_FLOOR,
        "left one source out: found {} of {}, below {LEFT_OUT_FLOOR}",
        all_left_out[0],
        photos.len()
    );
}
