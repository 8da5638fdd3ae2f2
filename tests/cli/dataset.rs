//! `reflectance dataset pack`: a CLASS/ILLUMINATION folder of photographs becomes the archive
//! the server's upload takes, every sphere located and every unusable file named; a folder
//! leave-one-illumination-out cannot use is refused without writing anything.

use crate::common;
use crate::render::{run, temp_dir};

use std::path::Path;

/// `classes` × `lights` folders, each holding one sphere photograph (r = 90 px).
fn photographs(dir: &Path, classes: &[&str], lights: &[&str]) {
    let png = common::sphere_png(200, 90.0);
    for class in classes {
        for light in lights {
            let folder = dir.join(class).join(light);
            std::fs::create_dir_all(&folder).unwrap();
            std::fs::write(folder.join("ball.png"), &png).unwrap();
        }
    }
}

#[test]
fn a_folder_of_photographs_is_packed_with_every_sphere_located() {
    let dir = temp_dir("dataset-pack");
    let folder = dir.join("photos");
    photographs(
        &folder,
        &["matte", "shiny"],
        &["kitchen", "garden", "office"],
    );
    std::fs::write(folder.join("shiny/office/broken.jpg"), b"not a jpeg").unwrap();
    std::fs::write(folder.join("shiny/office/notes.txt"), b"ignored").unwrap();
    let out = dir.join("photos.tar.gz");
    let packed = run(&[
        "dataset",
        "pack",
        folder.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    common::assert_success(&packed);
    let stdout = String::from_utf8_lossy(&packed.stdout);
    assert!(
        stdout.ends_with(
            "photos.tar.gz: 6 images (6 located here, 1 refused) of 2 classes under 3 illuminations\n"
        ),
        "{stdout}"
    );
    let stderr = String::from_utf8_lossy(&packed.stderr);
    assert!(
        stderr.contains("refused shiny/office/broken.jpg: "),
        "{stderr}"
    );

    let unpacked_dir = dir.join("unpacked");
    std::fs::create_dir_all(&unpacked_dir).unwrap();
    let limits = reflectance::ArchiveLimits {
        members: 100,
        unpacked_bytes: 1 << 24,
    };
    let unpacked = reflectance::unpack_archive(&out, &unpacked_dir, limits).unwrap();
    assert_eq!(unpacked.files.len(), 7, "{:?}", unpacked.files);
    let manifest =
        reflectance_core::dataset::read_manifest(&unpacked_dir.join("manifest.csv")).unwrap();
    assert_eq!(manifest.entries.len(), 6);
    for entry in &manifest.entries {
        let circle = entry.circle.expect("every row has its circle");
        assert!(
            (circle.r - 90.0).abs() < 2.0 && (circle.cx - 99.5).abs() < 2.0,
            "{entry:?}"
        );
        assert!(entry.file.is_file(), "{entry:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_folder_with_a_class_under_two_lights_is_refused_and_nothing_is_written() {
    let dir = temp_dir("dataset-pack-short");
    let folder = dir.join("photos");
    photographs(
        &folder,
        &["matte", "shiny"],
        &["kitchen", "garden", "office"],
    );
    std::fs::remove_dir_all(folder.join("matte/office")).unwrap();
    let out = dir.join("photos.tar.gz");
    let refused = run(&[
        "dataset",
        "pack",
        folder.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!refused.status.success());
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains("at least 3 illuminations") && stderr.contains("matte (2)"),
        "{stderr}"
    );
    assert!(!out.exists());
    let empty = run(&[
        "dataset",
        "pack",
        dir.join("nothing").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!empty.status.success());
    let _ = std::fs::remove_dir_all(&dir);
}
