//! Splitting a deterministic list of work into contiguous shards (`--shard I/N`, one per pod
//! of an indexed job), naming each shard's partial output file, and joining the parts of a
//! CSV file back into the file an unsharded run writes, byte for byte.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Why a shard cannot be named, or the parts of a file cannot be merged.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// A shard that is not `I/N`.
    #[error("expected I/N (shard I of N, zero-based: 0 ≤ I < N), not {0:?}")]
    Syntax(String),
    /// A shard count of 0.
    #[error("the shard count must be at least 1")]
    NoShards,
    /// A shard index not below the count.
    #[error("shard index {index} must be below the shard count {count} (indices are zero-based)")]
    Index {
        /// The zero-based index.
        index: usize,
        /// The shard count.
        count: usize,
    },
    /// Nothing to merge.
    #[error("no parts to merge")]
    NoParts,
    /// A file not named as a shard part: the file.
    #[error("{0}: not a shard part (expected NAME.shard-I-of-N[.EXT])")]
    NotAPart(String),
    /// Parts of different files: a part, its file, another part, its file.
    #[error("{0}: a part of {1}, but {2} is a part of {3}")]
    DifferentFiles(String, String, String, String),
    /// Parts of differently sharded runs: a part, its count, another part, its count.
    #[error("{0}: one of {1} shards, but {2} is one of {3}")]
    DifferentCounts(String, usize, String, usize),
    /// Two parts of the same shard.
    #[error("shard {index} of {count} is given twice: {first} and {second}")]
    Duplicate {
        /// The zero-based shard index.
        index: usize,
        /// The shard count.
        count: usize,
        /// The first part of the shard.
        first: String,
        /// The second.
        second: String,
    },
    /// Shards without a part.
    #[error("missing shard(s) {missing} of {count}")]
    Missing {
        /// The missing indices, comma-separated (the first 10, then an ellipsis).
        missing: String,
        /// The shard count.
        count: usize,
    },
    /// Parts whose CSV headers differ: a part and the first part.
    #[error("{0}: the header differs from that of {1} (parts of different runs?)")]
    Header(String, String),
    /// A part is not valid CSV.
    #[error("{path}: {detail}")]
    Csv {
        /// The part's path.
        path: String,
        /// The CSV reader's message.
        detail: String,
    },
    /// A part cannot be read, or the merge written.
    #[error("{path}: {source}")]
    Io {
        /// The file's path.
        path: String,
        /// The operating system's error.
        source: std::io::Error,
    },
}

/// Shard `index` of `count` (zero-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    index: usize,
    count: usize,
}

impl Shard {
    /// Shard `index` of `count`: `count` ≥ 1 and `index` < `count`.
    pub fn new(index: usize, count: usize) -> Result<Shard, ShardError> {
        match (index, count) {
            (_, 0) => Err(ShardError::NoShards),
            (index, count) if index >= count => Err(ShardError::Index { index, count }),
            _ => Ok(Shard { index, count }),
        }
    }

    /// The zero-based index.
    pub fn index(&self) -> usize {
        self.index
    }

    /// The shard count (≥ 1).
    pub fn count(&self) -> usize {
        self.count
    }

    /// This shard's items of a list of `len`: `[I·len/N, (I+1)·len/N)`, so that the blocks of
    /// shards 0…N−1 cover the list in order, their sizes differing by at most one.
    pub fn block(&self, len: usize) -> Range<usize> {
        // In u128, as I·len may not fit a usize.
        let at = |i: usize| (i as u128 * len as u128 / self.count as u128) as usize;
        at(self.index)..at(self.index + 1)
    }

    /// The partial file of this shard beside `path`: `dir/manifest.csv` →
    /// `dir/manifest.shard-2-of-4.csv`. The numbers are not padded, so that a Kubernetes
    /// Indexed Job can spell a pod's part as `…shard-$(JOB_COMPLETION_INDEX)-of-4.csv`;
    /// `merge` orders parts by their numbers, not by name.
    pub fn part_path(&self, path: &Path) -> PathBuf {
        let name = path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let (stem, extension) = split_extension(&name);
        let tag = format!("shard-{}-of-{}", self.index, self.count);
        path.with_file_name(format!("{stem}.{tag}{extension}"))
    }

    /// The shard a part's file name states and the name of the whole file.
    pub fn of_part(path: &Path) -> Result<(Shard, String), ShardError> {
        let not_a_part = || ShardError::NotAPart(path.display().to_string());
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(not_a_part)?;
        let (stem, tail) = name.rsplit_once(".shard-").ok_or_else(not_a_part)?;
        let (numbers, extension) = split_extension(tail);
        let (index, count) = numbers.split_once("-of-").ok_or_else(not_a_part)?;
        let number = |s: &str| {
            s.bytes()
                .all(|b| b.is_ascii_digit())
                .then(|| s.parse::<usize>().ok())
                .flatten()
                .ok_or_else(not_a_part)
        };
        let shard = Shard::new(number(index)?, number(count)?)
            .map_err(|e| ShardError::NotAPart(format!("{}: {e}", path.display())))?;
        Ok((shard, format!("{stem}{extension}")))
    }
}

/// `name.ext` → (`name`, `.ext`); a name without a dot (or only a leading one) has no
/// extension.
fn split_extension(name: &str) -> (&str, &str) {
    match name.rfind('.') {
        Some(dot) if dot > 0 => name.split_at(dot),
        _ => (name, ""),
    }
}

impl std::str::FromStr for Shard {
    type Err = ShardError;

    /// `I/N`, e.g. `2/4` (the third of four shards).
    fn from_str(text: &str) -> Result<Shard, ShardError> {
        let syntax = || ShardError::Syntax(text.to_string());
        let (index, count) = text.split_once('/').ok_or_else(syntax)?;
        let number = |s: &str| s.trim().parse::<usize>().map_err(|_| syntax());
        Shard::new(number(index)?, number(count)?)
    }
}

/// What [`merge`] joined.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Merged {
    /// Parts merged (the shard count).
    pub shards: usize,
    /// Records after the header.
    pub rows: usize,
}

/// Join the parts of one CSV file (manifest, feature table, capture settings), every shard
/// `0…N−1` of one run exactly once, in any order: the common header, then each part's rows
/// in shard order, bytes as they are; written to `out` atomically. Fails, writing nothing,
/// when the parts name different files or shard counts, a shard is missing or given twice,
/// the headers differ, or a part is not CSV with the header's number of columns.
pub fn merge(parts: &[PathBuf], out: &Path) -> Result<Merged, ShardError> {
    let ordered = in_shard_order(parts)?;
    let mut merged = Vec::new();
    let mut first: Option<(&Path, usize)> = None;
    let mut rows = 0;
    for path in &ordered {
        let bytes = std::fs::read(path).map_err(|source| ShardError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let part = CsvPart::parse(path, &bytes)?;
        let header = &bytes[..part.header_end];
        match first {
            None => {
                merged.extend_from_slice(header);
                first = Some((path, header.len()));
            }
            Some((first, len)) if merged.get(..len) != Some(header) => {
                return Err(ShardError::Header(
                    path.display().to_string(),
                    first.display().to_string(),
                ));
            }
            Some(_) => {}
        }
        let body = &bytes[part.header_end..];
        merged.extend_from_slice(body);
        if !body.is_empty() && !body.ends_with(b"\n") {
            merged.push(b'\n');
        }
        rows += part.rows;
    }
    crate::util::durable::write_atomic(out, &merged).map_err(|source| ShardError::Io {
        path: out.display().to_string(),
        source,
    })?;
    Ok(Merged {
        shards: ordered.len(),
        rows,
    })
}

/// The parts sorted by shard, after checking that they are the shards `0…N−1` of one file.
fn in_shard_order(parts: &[PathBuf]) -> Result<Vec<&Path>, ShardError> {
    let mut by_index: BTreeMap<usize, &Path> = BTreeMap::new();
    let mut first: Option<(&Path, Shard, String)> = None;
    for path in parts {
        let (shard, whole) = Shard::of_part(path)?;
        let shown = |p: &Path| p.display().to_string();
        if let Some((first, first_shard, first_whole)) = &first {
            if whole != *first_whole {
                return Err(ShardError::DifferentFiles(
                    shown(path),
                    whole,
                    shown(first),
                    first_whole.clone(),
                ));
            }
            if shard.count != first_shard.count {
                return Err(ShardError::DifferentCounts(
                    shown(path),
                    shard.count,
                    shown(first),
                    first_shard.count,
                ));
            }
        }
        if let Some(earlier) = by_index.insert(shard.index, path) {
            return Err(ShardError::Duplicate {
                index: shard.index,
                count: shard.count,
                first: shown(earlier),
                second: shown(path),
            });
        }
        first.get_or_insert((path, shard, whole));
    }
    let count = first.ok_or(ShardError::NoParts)?.1.count;
    if by_index.len() < count {
        return Err(ShardError::Missing {
            missing: missing_list(&by_index, count),
            count,
        });
    }
    Ok(by_index.into_values().collect())
}

/// The first few absent indices (the loop stops early: `count` may be huge).
fn missing_list(present: &BTreeMap<usize, &Path>, count: usize) -> String {
    const SHOWN: usize = 10;
    let mut missing = (0..count).filter(|i| !present.contains_key(i));
    let mut list: Vec<String> = missing
        .by_ref()
        .take(SHOWN)
        .map(|i| i.to_string())
        .collect();
    if missing.next().is_some() {
        list.push("…".into());
    }
    list.join(", ")
}

/// Where a CSV file's header record ends, and how many records follow it.
struct CsvPart {
    header_end: usize,
    rows: usize,
}

impl CsvPart {
    fn parse(path: &Path, bytes: &[u8]) -> Result<CsvPart, ShardError> {
        let error = |detail: String| ShardError::Csv {
            path: path.display().to_string(),
            detail,
        };
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(bytes);
        let mut record = csv::ByteRecord::new();
        let read = |reader: &mut csv::Reader<&[u8]>, record: &mut csv::ByteRecord| {
            reader
                .read_byte_record(record)
                .map_err(|e| error(e.to_string()))
        };
        if !read(&mut reader, &mut record)? {
            return Err(error("empty: no header".into()));
        }
        let header_end =
            usize::try_from(reader.position().byte()).map_err(|_| error("too large".into()))?;
        let mut rows = 0;
        // The reader refuses records whose length differs from the header's.
        while read(&mut reader, &mut record)? {
            rows += 1;
        }
        Ok(CsvPart { header_end, rows })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_blocks_cover_the_list_in_order() {
        for count in 1..=7 {
            for len in 0..=20 {
                let blocks: Vec<Range<usize>> = (0..count)
                    .map(|i| Shard::new(i, count).unwrap().block(len))
                    .collect();
                assert_eq!(blocks[0].start, 0);
                assert_eq!(blocks[count - 1].end, len);
                for pair in blocks.windows(2) {
                    assert_eq!(pair[0].end, pair[1].start);
                }
                let sizes = blocks.iter().map(Range::len);
                let (min, max) = (sizes.clone().min().unwrap(), sizes.max().unwrap());
                assert!(max - min <= 1, "{count} {len}: {blocks:?}");
            }
        }
        assert_eq!(Shard::new(2, 4).unwrap().block(10), 5..7);
    }

    #[test]
    fn parses_i_of_n_and_refuses_the_rest() {
        assert_eq!("2/4".parse::<Shard>().unwrap(), Shard::new(2, 4).unwrap());
        assert_eq!("0/1".parse::<Shard>().unwrap(), Shard::new(0, 1).unwrap());
        for bad in ["4/4", "0/0", "1", "a/2", "-1/4", "1/2/3", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn part_names_round_trip() {
        let shard = Shard::new(2, 4).unwrap();
        let part = shard.part_path(Path::new("out/manifest.csv"));
        assert_eq!(part, Path::new("out/manifest.shard-2-of-4.csv"));
        assert_eq!(
            Shard::of_part(&part).unwrap(),
            (shard, "manifest.csv".to_string())
        );
        let wide = Shard::new(7, 12345).unwrap().part_path(Path::new("table"));
        assert_eq!(wide, Path::new("table.shard-7-of-12345"));
        assert_eq!(Shard::of_part(&wide).unwrap().1, "table");
        for bad in [
            "manifest.csv",
            "m.shard-2-of-.csv",
            "m.shard-4-of-4.csv",
            "m.shard-+1-of-2",
        ] {
            assert!(Shard::of_part(Path::new(bad)).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_header_ends_after_its_terminator() {
        let text = b"a,\"b\nc\"\n1,2\n3,4";
        let part = CsvPart::parse(Path::new("x"), text).unwrap();
        assert_eq!(&text[..part.header_end], b"a,\"b\nc\"\n");
        assert_eq!(part.rows, 2);
        assert!(CsvPart::parse(Path::new("x"), b"a,b\n1\n").is_err());
        assert!(CsvPart::parse(Path::new("x"), b"").is_err());
    }
}
