//! Taking in a folder of labelled photographs: every manifest row's image is decoded and
//! checked, its sphere located where the row gives no circle, and what cannot be used is
//! refused with the reason while the rest is kept. The server's dataset upload and
//! `reflectance dataset pack` both use it.

use super::{DatasetError, Entry, Manifest, format_f64};
use crate::analysis::{self, Placement};
use crate::decode::{self, DecodeError, DecodeOptions};
use crate::features::polar::UnwrapConfig;
use crate::locate::GeometryError;
use crate::util::progress;
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path};

/// Leave-one-illumination-out needs every class under at least this many illuminations:
/// one held out, and two to learn from, so that a class is never learned from one light.
pub const MIN_ILLUMINATIONS: usize = 3;

/// A row (or an archive member) that cannot be used, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Refusal {
    /// The row's path (or the archive member's name).
    pub path: String,
    /// Why it cannot be used, for people.
    pub reason: String,
}

/// The usable rows, each with its circle, and the refused ones.
#[derive(Clone, Debug)]
pub struct Ingested {
    /// The usable rows, in manifest order, each with its circle.
    pub entries: Vec<Entry>,
    /// The refused rows, in manifest order.
    pub refused: Vec<Refusal>,
    /// Rows whose circle was found here rather than given.
    pub located: usize,
}

/// A manifest path that stays inside the manifest's folder: relative, without `..`.
pub fn is_inside(path: &str) -> bool {
    let path = Path::new(path);
    !path.as_os_str().is_empty()
        && !path.to_string_lossy().contains('\\')
        && path
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
}

/// Why a row of an uploaded dataset is refused.
#[derive(Debug, thiserror::Error)]
pub enum RowError {
    /// The row has no class.
    #[error("the row has no class")]
    NoClass,
    /// The row has no illumination.
    #[error("the row has no illumination")]
    NoIllumination,
    /// The row's path is absolute or climbs out of the folder.
    #[error("the path leaves the dataset's folder")]
    Outside,
    /// The row names no file of the dataset.
    #[error("no such image in the dataset")]
    Missing,
    /// The row gives a normal map or a mask: a dataset here holds spheres by their circle.
    #[error(
        "the row gives a normal map or a mask; datasets taken in here hold spheres by their \
         circle (train on objects from a manifest on disk: reflectance train --manifest)"
    )]
    NotByCircle,
    /// The image does not decode within the limits.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// The circle, given or found, does not fit the image.
    #[error("{0}{hint}", hint = match .0 {
        GeometryError::DetectionFailed { .. } => "; give cx, cy and r in the manifest",
        _ => "",
    })]
    Geometry(#[from] GeometryError),
}

/// Check one row: labelled, inside the folder, decodable within the limits, and with a
/// circle (given or found) whose annulus lies inside the image.
fn check(entry: &Entry, options: &DecodeOptions) -> Result<(Entry, bool), RowError> {
    match (&entry.class, &entry.illumination) {
        (None, _) => return Err(RowError::NoClass),
        (_, None) => return Err(RowError::NoIllumination),
        _ => {}
    }
    if !is_inside(&entry.path) {
        return Err(RowError::Outside);
    }
    if entry.normals.is_some() || entry.mask.is_some() {
        return Err(RowError::NotByCircle);
    }
    if !entry.file.is_file() {
        return Err(RowError::Missing);
    }
    let options = DecodeOptions {
        encoding: entry.encoding.or(options.encoding),
        ..*options
    };
    let image = decode::decode_file(&entry.file, &options)?;
    let how = entry.circle.map_or(Placement::Auto, Placement::Circle);
    let (geometry, _) = analysis::locate_for(&image, &how, &UnwrapConfig::default())?;
    let located = entry.circle.is_none();
    let mut kept = entry.clone();
    kept.circle = Some(geometry.circle());
    Ok((kept, located))
}

/// Check every row of `manifest` in parallel, in manifest order; a cancellation seen
/// before a row starts ends the run with [`DatasetError::Cancelled`].
pub fn ingest(
    manifest: &Manifest,
    options: &DecodeOptions,
    observer: &dyn progress::Observer,
) -> Result<Ingested, DatasetError> {
    let results = super::for_each_entry(manifest, observer, |entry| check(entry, options))?;
    let mut ingested = Ingested {
        entries: Vec::new(),
        refused: Vec::new(),
        located: 0,
    };
    for (entry, result) in manifest.entries.iter().zip(results) {
        match result {
            Ok((kept, located)) => {
                ingested.located += usize::from(located);
                ingested.entries.push(kept);
            }
            Err(reason) => ingested.refused.push(Refusal {
                path: entry.path.clone(),
                // Rows of a manifest file have a line; rows made from a folder have none.
                reason: match entry.line {
                    0 => reason.to_string(),
                    line => format!("manifest line {line}: {reason}"),
                },
            }),
        }
    }
    Ok(ingested)
}

/// The classes and illuminations of labelled rows.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Coverage {
    /// Each class with the illuminations it was photographed under.
    pub illuminations_of: BTreeMap<String, BTreeSet<String>>,
}

impl Coverage {
    /// The classes and illuminations of `entries` (rows without both labels are left out).
    pub fn of(entries: &[Entry]) -> Coverage {
        let mut coverage = Coverage::default();
        for e in entries {
            if let (Some(class), Some(light)) = (&e.class, &e.illumination) {
                coverage
                    .illuminations_of
                    .entry(class.clone())
                    .or_default()
                    .insert(light.clone());
            }
        }
        coverage
    }

    /// The classes, sorted.
    pub fn classes(&self) -> Vec<String> {
        self.illuminations_of.keys().cloned().collect()
    }

    /// Every illumination of any class, sorted.
    pub fn illuminations(&self) -> Vec<String> {
        let all: BTreeSet<&String> = self.illuminations_of.values().flatten().collect();
        all.into_iter().cloned().collect()
    }

    /// Why leave-one-illumination-out cannot run on these rows, if it cannot: fewer than
    /// two classes, or a class under fewer than [`MIN_ILLUMINATIONS`] illuminations.
    pub fn loio_problem(&self) -> Option<String> {
        if self.illuminations_of.len() < 2 {
            return Some(format!(
                "a classifier needs at least 2 classes; the usable images hold {}",
                self.illuminations_of.len()
            ));
        }
        let short: Vec<String> = self
            .illuminations_of
            .iter()
            .filter(|(_, lights)| lights.len() < MIN_ILLUMINATIONS)
            .map(|(class, lights)| format!("{class} ({})", lights.len()))
            .collect();
        (!short.is_empty()).then(|| {
            format!(
                "leave-one-illumination-out needs every class photographed under at least \
                 {MIN_ILLUMINATIONS} illuminations; too few usable for: {}",
                short.join(", ")
            )
        })
    }
}

/// The manifest of `entries`, every column written (`path,class,illumination,cx,cy,r,
/// white,encoding,normals,mask`); numbers in their shortest exact form.
pub fn manifest_csv(entries: &[Entry]) -> Vec<u8> {
    let mut out = String::from("path,class,illumination,cx,cy,r,white,encoding,normals,mask\n");
    let quote = |s: &str| {
        if s.contains([',', '"', '\n', '\r']) {
            format!("\"{}\"", s.replace('"', "\"\""))
        } else {
            s.to_string()
        }
    };
    for e in entries {
        let circle = e.circle.map_or_else(
            || [String::new(), String::new(), String::new()],
            |c| [format_f64(c.cx), format_f64(c.cy), format_f64(c.r)],
        );
        let fields = [
            quote(&e.path),
            quote(e.class.as_deref().unwrap_or_default()),
            quote(e.illumination.as_deref().unwrap_or_default()),
            circle[0].clone(),
            circle[1].clone(),
            circle[2].clone(),
            e.white.map(format_f64).unwrap_or_default(),
            e.encoding.map(|x| x.to_string()).unwrap_or_default(),
            e.normals
                .as_ref()
                .map(|b| quote(&b.path))
                .unwrap_or_default(),
            e.mask.as_ref().map(|b| quote(&b.path)).unwrap_or_default(),
        ];
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::read_manifest;

    #[test]
    fn paths_that_leave_the_folder_are_not_inside() {
        for good in ["a.png", "chrome/sun/1.jpg", "./a.png"] {
            assert!(is_inside(good), "{good}");
        }
        for bad in ["", "/etc/passwd", "../a.png", "a/../../b.png", "a\\b.png"] {
            assert!(!is_inside(bad), "{bad}");
        }
    }

    #[test]
    fn coverage_names_the_classes_short_of_illuminations() {
        let entry = |class: &str, light: &str| Entry {
            line: 2,
            path: "x.png".into(),
            file: "x.png".into(),
            class: Some(class.into()),
            illumination: Some(light.into()),
            circle: None,
            white: None,
            encoding: None,
            normals: None,
            mask: None,
        };
        let mut rows = vec![entry("chrome", "a"), entry("chrome", "b")];
        assert!(
            Coverage::of(&rows)
                .loio_problem()
                .unwrap()
                .contains("2 classes")
        );
        rows.extend([
            entry("matte", "a"),
            entry("matte", "b"),
            entry("matte", "c"),
        ]);
        let problem = Coverage::of(&rows).loio_problem().unwrap();
        assert!(
            problem.contains("chrome (2)") && !problem.contains("matte"),
            "{problem}"
        );
        rows.push(entry("chrome", "c"));
        let coverage = Coverage::of(&rows);
        assert_eq!(coverage.loio_problem(), None);
        assert_eq!(coverage.classes(), ["chrome", "matte"]);
        assert_eq!(coverage.illuminations(), ["a", "b", "c"]);
    }

    #[test]
    fn a_written_manifest_reads_back_the_same() {
        let dir = std::env::temp_dir().join(format!("ingest-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let beside = |path: &str| {
            Some(crate::dataset::Beside {
                path: path.into(),
                file: dir.join(path),
            })
        };
        let sphere = Entry {
            line: 2,
            path: "a, \"b\".png".into(),
            file: dir.join("a, \"b\".png"),
            class: Some("chrome".into()),
            illumination: Some("sun".into()),
            circle: Some(crate::locate::Circle {
                cx: 10.25,
                cy: 0.1 + 0.2,
                r: 40.0,
            }),
            white: Some(0.75),
            encoding: Some(decode::Encoding::Gamma(2.2)),
            normals: None,
            mask: None,
        };
        let object = Entry {
            line: 3,
            circle: None,
            normals: beside("n, 1.png"),
            mask: beside("m.png"),
            ..sphere.clone()
        };
        let refused = check(&object, &DecodeOptions::default()).unwrap_err();
        assert!(matches!(refused, RowError::NotByCircle), "{refused}");
        let entries = vec![sphere, object];
        let path = dir.join("manifest.csv");
        std::fs::write(&path, manifest_csv(&entries)).unwrap();
        let back = read_manifest(&path).unwrap().entries;
        assert_eq!(back.len(), 2);
        for (a, b) in entries.iter().zip(&back) {
            assert_eq!((&a.path, &a.file, &a.class), (&b.path, &b.file, &b.class));
            assert_eq!(
                (a.circle, a.white, a.encoding),
                (b.circle, b.white, b.encoding)
            );
            assert_eq!((&a.normals, &a.mask), (&b.normals, &b.mask));
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
