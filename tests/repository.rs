//! The repository's own rules: every source file of every crate is on the map of
//! docs/architecture.md, under its crate's heading, and the map names no file that is gone.

use std::collections::BTreeSet;
use std::path::Path;

/// Each crate's source folder and the heading of its section on the map.
const CRATES: [(&str, &str); 4] = [
    ("crates/reflectance-core/src", "## `reflectance-core`"),
    ("crates/reflectance-render/src", "## `reflectance-render`"),
    ("src", "## `reflectance` (`src/`)"),
    ("python/src", "## `reflectance-py`"),
];

fn sources(root: &Path, folder: &Path, out: &mut BTreeSet<String>) {
    for entry in std::fs::read_dir(folder).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(root, &path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let relative = path.strip_prefix(root).unwrap();
            out.insert(relative.to_string_lossy().replace('\\', "/"));
        }
    }
}

/// The files a section's table names: the first cell of each row, in backticks.
fn mapped(section: &str) -> BTreeSet<String> {
    section
        .lines()
        .filter_map(|line| line.strip_prefix("| `"))
        .filter_map(|rest| rest.split_once('`'))
        .map(|(file, _)| file.to_string())
        .filter(|file| file.ends_with(".rs"))
        .collect()
}

#[test]
fn every_source_file_is_on_the_architecture_map() {
    let repository = Path::new(env!("CARGO_MANIFEST_DIR"));
    let map = std::fs::read_to_string(repository.join("docs/architecture.md")).unwrap();
    for (folder, heading) in CRATES {
        let start = map
            .find(heading)
            .unwrap_or_else(|| panic!("docs/architecture.md has no section {heading:?}"));
        let section = &map[start + heading.len()..];
        let section = &section[..section.find("\n## ").unwrap_or(section.len())];
        let root = repository.join(folder);
        let mut files = BTreeSet::new();
        sources(&root, &root, &mut files);
        let on_map = mapped(section);
        let missing: Vec<_> = files.difference(&on_map).collect();
        let gone: Vec<_> = on_map.difference(&files).collect();
        assert!(
            missing.is_empty() && gone.is_empty(),
            "docs/architecture.md, {heading}: not on the map {missing:?}; on the map but gone {gone:?}"
        );
    }
}
