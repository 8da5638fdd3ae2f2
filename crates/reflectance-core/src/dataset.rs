//! Dataset manifests (`path,class,illumination[,cx,cy,r,white,encoding,normals,mask]`,
//! paths relative to the manifest's folder) and feature tables
//! (`path,class,illumination,<feature names>`).

use crate::analysis::{self, AnalysisError, Placement, WhiteSpec};
use crate::decode::{self, DecodeOptions};
use crate::features::{CaptureMeasurements, Extractor};
use crate::locate::Circle;
use crate::util::progress;
use crate::util::shard::Shard;
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

pub mod ingest;

/// Why a manifest, a feature table or one of their images cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// A file cannot be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file, as given.
        path: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A CSV file is malformed.
    #[error("{path}: {detail}")]
    Csv {
        /// The file, as given.
        path: String,
        /// The CSV reader's message.
        detail: String,
    },
    /// A manifest lacks its required `path` column.
    #[error("{path}: missing required column {column:?}")]
    MissingColumn {
        /// The manifest, as given.
        path: String,
        /// The column's name.
        column: String,
    },
    /// A row breaks a rule (a value that is not a number, a bad circle, white or encoding).
    #[error("{path} line {line}: {detail}")]
    Row {
        /// The manifest or table, as given.
        path: String,
        /// The row's 1-based line number (the header is line 1).
        line: u64,
        /// What is wrong.
        detail: String,
    },
    /// A manifest row's image gives no features.
    #[error("{path} line {line} ({image}): {source}")]
    Image {
        /// The manifest, as given.
        path: String,
        /// The row's 1-based line number (the header is line 1).
        line: u64,
        /// The image's path, as the row gives it.
        image: String,
        /// Why it gives no features.
        source: AnalysisError,
    },
    /// A feature table does not start with the `path,class,illumination` columns.
    #[error("{path}: {detail}")]
    Table {
        /// The table, as given.
        path: String,
        /// What is wrong.
        detail: String,
    },
    /// The caller cancelled the work.
    #[error("cancelled")]
    Cancelled,
}

/// One manifest row.
#[derive(Clone, Debug)]
pub struct Entry {
    /// 1-based line number in the file (the header is line 1).
    pub line: u64,
    /// As written in the manifest.
    pub path: String,
    /// Resolved against the manifest's folder.
    pub file: PathBuf,
    /// The class label, when the manifest has the column (required for training).
    pub class: Option<String>,
    /// The illumination (light probe) label: cross-validation holds out one at a time.
    pub illumination: Option<String>,
    /// The sphere's circle in the image's pixels; `None`: found by detection.
    pub circle: Option<Circle>,
    /// The white reference of the image (linear luminance, > 0); `None`: white = 1.
    pub white: Option<f64>,
    /// How the file's integer samples decode (`srgb`, `linear`, `gamma:<g>`); unset: the
    /// extraction's default.
    pub encoding: Option<decode::Encoding>,
    /// An object of any shape: its normal map (docs/design.md §8), instead of a circle.
    pub normals: Option<Beside>,
    /// Which pixels are the sphere or the object (nonzero, or alpha), instead of a circle.
    pub mask: Option<Beside>,
}

/// A file a manifest row names beside its image: its normal map or its mask.
#[derive(Clone, Debug, PartialEq)]
pub struct Beside {
    /// As written in the manifest.
    pub path: String,
    /// Resolved against the manifest's folder.
    pub file: PathBuf,
}

impl Entry {
    /// Where the row's object is, its files decoded ([`Placement::decode`]); the manifest
    /// refuses a circle with normals or a mask.
    pub fn placement(&self, options: &DecodeOptions) -> Result<Placement, AnalysisError> {
        let read = |b: &Option<Beside>| {
            b.as_ref()
                .map(|b| std::fs::read(&b.file).map_err(decode::DecodeError::Io))
                .transpose()
        };
        let (mask, normals) = (read(&self.mask)?, read(&self.normals)?);
        let placement = match (self.circle, mask, normals) {
            (_, mask, Some(normals)) => Placement::Normals { normals, mask },
            (_, Some(mask), None) => Placement::Mask(mask),
            (Some(circle), None, None) => Placement::Circle(circle),
            (None, None, None) => Placement::Auto,
        };
        Ok(placement.decode(options)?)
    }
}

/// A manifest's rows, as read: which images, their labels and how to read them.
#[derive(Clone, Debug)]
pub struct Manifest {
    /// The manifest file, as given.
    pub source: PathBuf,
    /// The rows, in file order.
    pub entries: Vec<Entry>,
}

fn display(path: &Path) -> String {
    path.display().to_string()
}

fn csv_error(path: &Path, e: csv::Error) -> DatasetError {
    let line = e.position().map(|p| p.line());
    match line {
        Some(line) => DatasetError::Row {
            path: display(path),
            line,
            detail: e.to_string(),
        },
        None => DatasetError::Csv {
            path: display(path),
            detail: e.to_string(),
        },
    }
}

fn open_csv(path: &Path) -> Result<csv::Reader<std::fs::File>, DatasetError> {
    let file = std::fs::File::open(path).map_err(|source| DatasetError::Io {
        path: display(path),
        source,
    })?;
    Ok(csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(file))
}

/// Read a manifest. `path` is required; `class`, `illumination` and the geometry and white
/// columns are optional (commands that need a class say so).
pub fn read_manifest(path: &Path) -> Result<Manifest, DatasetError> {
    let mut reader = open_csv(path)?;
    let header = reader.headers().map_err(|e| csv_error(path, e))?.clone();
    let column = |name: &str| header.iter().position(|h| h == name);
    let path_col = column("path").ok_or_else(|| DatasetError::MissingColumn {
        path: display(path),
        column: "path".into(),
    })?;
    let cols = [
        "class",
        "illumination",
        "cx",
        "cy",
        "r",
        "white",
        "encoding",
        "normals",
        "mask",
    ]
    .map(column);
    let base = path.parent().unwrap_or(Path::new("."));
    let mut entries = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| csv_error(path, e))?;
        let line = record.position().map_or(0, |p| p.line());
        let bad = |detail: String| DatasetError::Row {
            path: display(path),
            line,
            detail,
        };
        let text = |c: Option<usize>| c.and_then(|c| record.get(c)).filter(|s| !s.is_empty());
        let number = |name: &str, c: Option<usize>| -> Result<Option<f64>, DatasetError> {
            text(c)
                .map(|s| {
                    s.parse::<f64>()
                        .map_err(|_| bad(format!("{name} is not a number: {s:?}")))
                })
                .transpose()
        };
        let rel = text(Some(path_col)).ok_or_else(|| bad("empty path".into()))?;
        let [
            class,
            illumination,
            cx,
            cy,
            r,
            white,
            encoding,
            normals,
            mask,
        ] = cols;
        let encoding = text(encoding)
            .map(|e| {
                decode::Encoding::parse(e).ok_or_else(|| {
                    bad(format!(
                        "encoding must be srgb, linear or gamma:<g>, not {e:?}"
                    ))
                })
            })
            .transpose()?;
        let circle = match (number("cx", cx)?, number("cy", cy)?, number("r", r)?) {
            (Some(cx), Some(cy), Some(r)) => Some(Circle { cx, cy, r }),
            (None, None, None) => None,
            _ => return Err(bad("give all of cx, cy and r, or none".into())),
        };
        let beside = |c: Option<usize>| {
            text(c).map(|p| Beside {
                path: p.to_string(),
                file: base.join(p),
            })
        };
        let (normals, mask) = (beside(normals), beside(mask));
        if circle.is_some() && (normals.is_some() || mask.is_some()) {
            return Err(bad(
                "give a circle (cx, cy, r), or normals and/or a mask, not both".into(),
            ));
        }
        entries.push(Entry {
            line,
            path: rel.to_string(),
            file: base.join(rel),
            class: text(class).map(str::to_string),
            illumination: text(illumination).map(str::to_string),
            circle,
            white: number("white", white)?,
            encoding,
            normals,
            mask,
        });
    }
    Ok(Manifest {
        source: path.to_path_buf(),
        entries,
    })
}

impl Manifest {
    /// The rows of several manifests as one. With more than one, each row's paths are
    /// prefixed with its manifest's folder (so that rows of different folders stay apart)
    /// and the source names them all, joined by " + ".
    pub fn concat(mut manifests: Vec<Manifest>) -> Manifest {
        if manifests.len() == 1 {
            return manifests.remove(0);
        }
        let source = manifests
            .iter()
            .map(|m| display(&m.source))
            .collect::<Vec<_>>();
        let mut entries = Vec::new();
        for manifest in manifests {
            let folder = manifest.source.parent().unwrap_or(Path::new(""));
            let within = |path: &mut String| *path = display(&folder.join(&*path));
            for mut entry in manifest.entries {
                within(&mut entry.path);
                for beside in [&mut entry.normals, &mut entry.mask].into_iter().flatten() {
                    within(&mut beside.path);
                }
                entries.push(entry);
            }
        }
        Manifest {
            source: PathBuf::from(source.join(" + ")),
            entries,
        }
    }

    /// Only the rows of `shard`'s block (their line numbers kept for errors).
    pub fn shard(mut self, shard: Shard) -> Manifest {
        let block = shard.block(self.entries.len());
        self.entries = self.entries.drain(block).collect();
        self
    }

    /// Fails with the first row lacking a class or illumination.
    pub fn require_labels(&self) -> Result<(), DatasetError> {
        for e in &self.entries {
            let missing = match (&e.class, &e.illumination) {
                (None, _) => "class",
                (_, None) => "illumination",
                _ => continue,
            };
            return Err(DatasetError::Row {
                path: display(&self.source),
                line: e.line,
                detail: format!("missing {missing}"),
            });
        }
        Ok(())
    }
}

/// One row of a feature table.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// The image's path, as its manifest gives it.
    pub path: String,
    /// Its class.
    pub class: String,
    /// Its illumination (light probe).
    pub illumination: String,
    /// Its features, in the table's column order.
    pub values: Vec<f64>,
}

/// A feature the table has no column for.
#[derive(Debug, thiserror::Error)]
#[error("no column {0}")]
pub struct MissingColumn(pub String);

/// Features of many images as a table: one row per image, one column per feature (CSV as
/// `reflectance features --out` writes it).
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureTable {
    /// Feature names, in column order (canonical order when written by extraction).
    pub names: Vec<String>,
    /// The rows, in file order.
    pub samples: Vec<Sample>,
}

/// Features of one manifest entry: decode, locate ([`Entry::placement`]), normalize
/// (row white, or none: 1), extract.
pub fn extract_entry(
    extractor: &Extractor,
    entry: &Entry,
    options: &DecodeOptions,
) -> Result<Vec<f64>, AnalysisError> {
    Ok(extract_entry_measured(extractor, entry, options, false)?.0)
}

/// [`extract_entry`], with the capture measurements when `measure` (a photographed sphere's:
/// `None` for an object).
pub fn extract_entry_measured(
    extractor: &Extractor,
    entry: &Entry,
    options: &DecodeOptions,
    measure: bool,
) -> Result<(Vec<f64>, Option<CaptureMeasurements>), AnalysisError> {
    let options = DecodeOptions {
        encoding: entry.encoding.or(options.encoding),
        ..*options
    };
    // The photograph read as a request reads it (decode::Photo): what a model learns from
    // is what it will be shown.
    let bytes = std::fs::read(&entry.file).map_err(decode::DecodeError::Io)?;
    let photo = decode::Photo::open(&bytes, &options)?;
    let placement = entry.placement(&options)?;
    let white = entry.white.map_or(WhiteSpec::Missing, WhiteSpec::Value);
    let (analysis, _) =
        analysis::analyze_photo(extractor, &photo, &placement, &white, None, measure)?;
    Ok((analysis.values, analysis.measured))
}

/// `work` on every entry, in parallel, results in manifest order, each finished entry
/// reported to `observer`; a cancellation seen
/// before an entry starts ends the run with [`DatasetError::Cancelled`].
pub(crate) fn for_each_entry<T: Send>(
    manifest: &Manifest,
    observer: &dyn progress::Observer,
    work: impl Fn(&Entry) -> T + Sync,
) -> Result<Vec<T>, DatasetError> {
    let counter = progress::Counter::new(observer, manifest.entries.len());
    let results: Vec<Option<T>> = manifest
        .entries
        .par_iter()
        .map(|entry| {
            if counter.cancelled() {
                return None;
            }
            let result = work(entry);
            counter.tick();
            Some(result)
        })
        .collect();
    results
        .into_iter()
        .collect::<Option<Vec<T>>>()
        .ok_or(DatasetError::Cancelled)
}

/// Features of every entry, in parallel, in manifest order; the first failing row (by line)
/// fails the whole run.
pub fn extract_manifest(
    extractor: &Extractor,
    manifest: &Manifest,
    options: &DecodeOptions,
) -> Result<FeatureTable, DatasetError> {
    extract_manifest_with(extractor, manifest, options, &progress::Silent)
}

/// [`extract_manifest`] reporting each finished image to `observer`; a cancellation seen
/// before an image starts ends the run with [`DatasetError::Cancelled`].
pub fn extract_manifest_with(
    extractor: &Extractor,
    manifest: &Manifest,
    options: &DecodeOptions,
    observer: &dyn progress::Observer,
) -> Result<FeatureTable, DatasetError> {
    Ok(extract_manifest_measured(extractor, manifest, options, observer, false)?.0)
}

/// [`extract_manifest_with`], with each entry's capture measurements when `measure` (as
/// the service measures a request: `predict`).
pub fn extract_manifest_measured(
    extractor: &Extractor,
    manifest: &Manifest,
    options: &DecodeOptions,
    observer: &dyn progress::Observer,
    measure: bool,
) -> Result<(FeatureTable, Vec<Option<CaptureMeasurements>>), DatasetError> {
    let results = for_each_entry(manifest, observer, |entry| {
        extract_entry_measured(extractor, entry, options, measure)
    })?;
    let mut samples = Vec::with_capacity(manifest.entries.len());
    let mut measured = Vec::with_capacity(manifest.entries.len());
    for (entry, result) in manifest.entries.iter().zip(results) {
        let (values, measurements) = result.map_err(|source| DatasetError::Image {
            path: display(&manifest.source),
            line: entry.line,
            image: entry.path.clone(),
            source,
        })?;
        samples.push(Sample {
            path: entry.path.clone(),
            class: entry.class.clone().unwrap_or_default(),
            illumination: entry.illumination.clone().unwrap_or_default(),
            values,
        });
        measured.push(measurements);
    }
    let table = FeatureTable {
        names: extractor.config().names(),
        samples,
    };
    Ok((table, measured))
}

/// Shortest representation that reads back to the same f64.
pub fn format_f64(v: f64) -> String {
    if v.is_finite() {
        ryu::Buffer::new().format_finite(v).to_string()
    } else {
        v.to_string()
    }
}

/// The illumination group of procedural maps (`synthetic@<id>`, see `render::synthetic`):
/// like every `@` row, training only; having no original rows, it is never held out.
pub const SYNTHETIC_ILLUMINATION: &str = "synthetic";

/// Whether an illumination label names a synthetic map.
pub fn is_synthetic(illumination: &str) -> bool {
    illumination
        .split_once('@')
        .is_some_and(|(group, _)| group == SYNTHETIC_ILLUMINATION)
}

const LABEL_COLUMNS: [&str; 3] = ["path", "class", "illumination"];

impl FeatureTable {
    /// The table as CSV, exactly as [`FeatureTable::write`] stores it.
    pub fn to_csv(&self) -> Vec<u8> {
        let mut out = csv::Writer::from_writer(Vec::new());
        let header = LABEL_COLUMNS
            .iter()
            .copied()
            .chain(self.names.iter().map(String::as_str));
        // Writing records into memory cannot fail.
        let _ = out.write_record(header);
        for s in &self.samples {
            let labels = [s.path.clone(), s.class.clone(), s.illumination.clone()];
            let values = s.values.iter().map(|&v| format_f64(v));
            let _ = out.write_record(labels.into_iter().chain(values));
        }
        out.into_inner().unwrap_or_default()
    }

    /// Write the table as CSV, atomically (a reader never sees half a file).
    pub fn write(&self, path: &Path) -> Result<(), DatasetError> {
        crate::util::durable::write_atomic(path, &self.to_csv()).map_err(|source| {
            DatasetError::Io {
                path: display(path),
                source,
            }
        })
    }

    /// Read a table written by [`FeatureTable::write`].
    pub fn read(path: &Path) -> Result<FeatureTable, DatasetError> {
        let mut reader = open_csv(path)?;
        let header = reader.headers().map_err(|e| csv_error(path, e))?.clone();
        let table_error = |detail: String| DatasetError::Table {
            path: display(path),
            detail,
        };
        let labels: Vec<&str> = header.iter().take(3).collect();
        if labels != LABEL_COLUMNS {
            return Err(table_error(format!(
                "expected the columns to start with path,class,illumination, found {labels:?}"
            )));
        }
        let names: Vec<String> = header.iter().skip(3).map(str::to_string).collect();
        let mut samples = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| csv_error(path, e))?;
            let line = record.position().map_or(0, |p| p.line());
            let values = record
                .iter()
                .skip(3)
                .zip(&names)
                .map(|(text, name)| {
                    text.parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| DatasetError::Row {
                            path: display(path),
                            line,
                            detail: format!("{name} is not a finite number: {text:?}"),
                        })
                })
                .collect::<Result<Vec<f64>, _>>()?;
            samples.push(Sample {
                path: record[0].to_string(),
                class: record[1].to_string(),
                illumination: record[2].to_string(),
                values,
            });
        }
        Ok(FeatureTable { names, samples })
    }

    /// The table restricted to the given columns (which must exist), in that order.
    pub fn with_columns(&self, names: &[String]) -> Result<FeatureTable, MissingColumn> {
        let idx = self.columns(names)?;
        let samples = self
            .samples
            .iter()
            .map(|s| Sample {
                values: idx.iter().map(|&i| s.values[i]).collect(),
                ..s.clone()
            })
            .collect();
        Ok(FeatureTable {
            names: names.to_vec(),
            samples,
        })
    }

    /// The rows of original renders only (illuminations without an `@` view suffix).
    pub fn originals(&self) -> FeatureTable {
        self.filtered(|illumination| !illumination.contains('@'))
    }

    /// Every row but those of synthetic illuminations.
    pub fn without_synthetic(&self) -> FeatureTable {
        self.filtered(|illumination| !is_synthetic(illumination))
    }

    fn filtered(&self, keep: impl Fn(&str) -> bool) -> FeatureTable {
        FeatureTable {
            names: self.names.clone(),
            samples: self
                .samples
                .iter()
                .filter(|s| keep(&s.illumination))
                .cloned()
                .collect(),
        }
    }

    /// Column index of every name, or the first unknown name.
    pub fn columns(&self, wanted: &[String]) -> Result<Vec<usize>, MissingColumn> {
        let index: HashMap<&str, usize> = self
            .names
            .iter()
            .enumerate()
            .map(|(i, n)| (n.as_str(), i))
            .collect();
        wanted
            .iter()
            .map(|w| {
                index
                    .get(w.as_str())
                    .copied()
                    .ok_or_else(|| MissingColumn(w.clone()))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn manifest(name: &str, text: &str) -> Result<Manifest, DatasetError> {
        let dir = std::env::temp_dir().join(format!("manifest-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("manifest.csv");
        std::fs::write(&path, text).unwrap();
        let read = read_manifest(&path);
        let _ = std::fs::remove_dir_all(&dir);
        read
    }

    #[test]
    fn manifests_concatenated_keep_their_rows_apart_by_folder() {
        let dir = std::env::temp_dir().join(format!("manifest-concat-{}", std::process::id()));
        let (a, b) = (dir.join("spheres"), dir.join("tori"));
        for (folder, text) in [
            (&a, "path,class,illumination,cx,cy,r\nx.pfm,c,p,10,10,40\n"),
            (
                &b,
                "path,class,illumination,normals\nx.pfm,c,p,x.normals.png\n",
            ),
        ] {
            std::fs::create_dir_all(folder).unwrap();
            std::fs::write(folder.join("manifest.csv"), text).unwrap();
        }
        let read = |f: &Path| read_manifest(&f.join("manifest.csv")).unwrap();
        let one = Manifest::concat(vec![read(&a)]);
        assert_eq!(one.entries[0].path, "x.pfm");
        let both = Manifest::concat(vec![read(&a), read(&b)]);
        let _ = std::fs::remove_dir_all(&dir);
        let paths: Vec<&str> = both.entries.iter().map(|e| e.path.as_str()).collect();
        let (sphere, torus) = (display(&a.join("x.pfm")), display(&b.join("x.pfm")));
        assert_eq!(paths, [sphere.as_str(), torus.as_str()]);
        let normals = both.entries[1].normals.as_ref().unwrap();
        assert_eq!(normals.path, display(&b.join("x.normals.png")));
        assert_eq!(normals.file, b.join("x.normals.png"));
        assert!(display(&both.source).contains(" + "));
    }

    #[test]
    fn a_row_is_placed_by_its_normals_its_mask_or_its_circle_never_two() {
        let read = manifest(
            "placed",
            "path,class,cx,cy,r,normals,mask\n\
             a.png,x,,,,a.normals.png,a.mask.png\n\
             b.png,x,,,,,b.mask.png\n\
             c.png,x,10,10,40,,\n",
        )
        .unwrap();
        let [a, b, c] = [0, 1, 2].map(|i| &read.entries[i]);
        let beside = |e: &Entry| {
            (
                e.normals.clone().map(|n| n.path),
                e.mask.clone().map(|m| m.path),
            )
        };
        assert_eq!(
            beside(a),
            (Some("a.normals.png".into()), Some("a.mask.png".into()))
        );
        assert_eq!(
            a.normals.as_ref().unwrap().file,
            a.file.with_file_name("a.normals.png")
        );
        assert_eq!(beside(b), (None, Some("b.mask.png".into())));
        assert_eq!(
            (beside(c), c.circle.map(|c| c.r)),
            ((None, None), Some(40.0))
        );
        let both = manifest("both", "path,cx,cy,r,normals\nd.png,1,2,40,d.normals.png\n");
        let error = both.unwrap_err().to_string();
        assert!(
            error.contains("line 2") && error.contains("not both"),
            "{error}"
        );
    }
}
