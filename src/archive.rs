//! Dataset archives (`.tar`, `.tar.gz`, `.zip`): unpacked safely into a folder, and made
//! from one. Unpacking writes regular files only, each created new under the folder; a
//! member with an absolute path, a `..` component, a link or a device is refused by name,
//! and limits on the number of members and the bytes unpacked (counted as they are
//! written, whatever the archive declares) end the whole unpacking.

use reflectance_core::dataset::ingest::Refusal;
use std::collections::BTreeSet;
use std::fs::File;
use std::io::{self, BufReader, Read, Seek, Write};
use std::path::{Path, PathBuf};

/// What an archive may hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArchiveLimits {
    /// Members, directories included.
    pub members: usize,
    /// Bytes of all regular files, unpacked.
    pub unpacked_bytes: u64,
}

#[derive(Debug, thiserror::Error)]
pub enum ArchiveError {
    #[error("the archive is not a tar, tar.gz or zip file")]
    UnknownFormat,
    #[error("the archive cannot be read: {0}")]
    Corrupt(String),
    #[error("the archive has more than {limit} members (the limit; see --dataset-max-members)")]
    TooManyMembers { limit: usize },
    #[error(
        "the archive unpacks to more than {limit} bytes (the limit; see --dataset-max-unpacked)"
    )]
    TooLarge { limit: u64 },
    #[error("{path}: {source}")]
    Io { path: String, source: io::Error },
}

/// The regular files unpacked (their archive paths, `/`-separated) and the members
/// refused.
#[derive(Debug, Default)]
pub struct Unpacked {
    pub files: BTreeSet<String>,
    pub refused: Vec<Refusal>,
    pub bytes: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Tar,
    TarGz,
    Zip,
}

fn sniff(file: &mut File) -> Result<Format, ArchiveError> {
    let mut head = [0u8; 263];
    let mut read = 0;
    while read < head.len() {
        match file.read(&mut head[read..]) {
            Ok(0) => break,
            Ok(n) => read += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(ArchiveError::Corrupt(e.to_string())),
        }
    }
    file.rewind()
        .map_err(|e| ArchiveError::Corrupt(e.to_string()))?;
    let head = &head[..read];
    if head.starts_with(&[0x1f, 0x8b]) {
        Ok(Format::TarGz)
    } else if head.starts_with(b"PK\x03\x04") || head.starts_with(b"PK\x05\x06") {
        Ok(Format::Zip)
    } else if head.len() >= 262 && &head[257..262] == b"ustar" {
        Ok(Format::Tar)
    } else {
        Err(ArchiveError::UnknownFormat)
    }
}

/// A member's name as a safe relative path, or why it is refused.
fn member_path(name: &str) -> Result<String, &'static str> {
    if name.contains('\0') || name.contains('\\') {
        return Err("the name holds a NUL or a backslash");
    }
    if name.starts_with('/') {
        return Err("absolute paths are not accepted");
    }
    let mut parts = Vec::new();
    for part in name.split('/') {
        match part {
            "" | "." => {}
            ".." => return Err("'..' is not accepted in a member's path"),
            part => parts.push(part),
        }
    }
    if parts.is_empty() {
        return Err("empty name");
    }
    if parts[0].len() == 2 && parts[0].ends_with(':') {
        return Err("drive letters are not accepted");
    }
    Ok(parts.join("/"))
}

/// What kind of member an archive entry is.
enum Member {
    File,
    Dir,
    /// Metadata the format uses internally (a pax global header): nothing to unpack.
    Skip,
    Refused(&'static str),
}

/// Unpacking state: the destination, the limits and what was written so far.
struct Sink<'a> {
    dest: &'a Path,
    limits: ArchiveLimits,
    members: usize,
    unpacked: Unpacked,
}

impl Sink<'_> {
    fn count_member(&mut self) -> Result<(), ArchiveError> {
        self.members += 1;
        if self.members > self.limits.members {
            return Err(ArchiveError::TooManyMembers {
                limit: self.limits.members,
            });
        }
        Ok(())
    }

    fn refuse(&mut self, path: &str, reason: impl Into<String>) {
        self.unpacked.refused.push(Refusal {
            path: path.to_string(),
            reason: reason.into(),
        });
    }

    /// Write one member: refused by name when its path or kind is not acceptable, else
    /// created new (never overwritten) with its bytes counted against the limit.
    fn member(
        &mut self,
        name: &str,
        kind: Member,
        data: &mut dyn Read,
    ) -> Result<(), ArchiveError> {
        self.count_member()?;
        let rel = match (member_path(name), kind) {
            (_, Member::Skip | Member::Dir) => return Ok(()),
            (Err(reason), _) | (_, Member::Refused(reason)) => {
                self.refuse(name, reason);
                return Ok(());
            }
            (Ok(rel), Member::File) => rel,
        };
        if self.unpacked.files.contains(&rel) {
            self.refuse(name, "a second member with the same path");
            return Ok(());
        }
        let path = self.dest.join(&rel);
        let io_error = |source| ArchiveError::Io {
            path: rel.clone(),
            source,
        };
        let created = path
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .and_then(|()| File::create_new(&path));
        let mut file = match created {
            Ok(file) => file,
            // A file where a folder must go, or the reverse: this member cannot be placed.
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::AlreadyExists | io::ErrorKind::NotADirectory
                ) =>
            {
                self.refuse(name, format!("cannot be placed: {e}"));
                return Ok(());
            }
            Err(e) => return Err(io_error(e)),
        };
        let room = self.limits.unpacked_bytes - self.unpacked.bytes;
        let written = io::copy(&mut data.take(room + 1), &mut file).map_err(|e| {
            if is_storage(&e) {
                io_error(e)
            } else {
                ArchiveError::Corrupt(format!("{rel}: {e}"))
            }
        })?;
        if written > room {
            return Err(ArchiveError::TooLarge {
                limit: self.limits.unpacked_bytes,
            });
        }
        self.unpacked.bytes += written;
        self.unpacked.files.insert(rel);
        Ok(())
    }
}

/// Errors of the disk we write to (as opposed to the archive's own data).
fn is_storage(e: &io::Error) -> bool {
    use io::ErrorKind as E;
    matches!(
        e.kind(),
        E::StorageFull
            | E::FileTooLarge
            | E::QuotaExceeded
            | E::ReadOnlyFilesystem
            | E::PermissionDenied
    )
}

fn tar_kind(entry_type: tar::EntryType) -> Member {
    use tar::EntryType as T;
    match entry_type {
        T::Regular | T::Continuous => Member::File,
        T::Directory => Member::Dir,
        T::XGlobalHeader => Member::Skip,
        T::Symlink | T::Link => Member::Refused("links are not accepted"),
        _ => Member::Refused("not a regular file"),
    }
}

fn unpack_tar(reader: impl Read, sink: &mut Sink) -> Result<(), ArchiveError> {
    let corrupt = |e: io::Error| ArchiveError::Corrupt(e.to_string());
    let mut archive = tar::Archive::new(reader);
    for entry in archive.entries().map_err(corrupt)? {
        let mut entry = entry.map_err(corrupt)?;
        let name = String::from_utf8_lossy(&entry.path_bytes()).into_owned();
        let kind = tar_kind(entry.header().entry_type());
        sink.member(&name, kind, &mut entry)?;
    }
    Ok(())
}

fn unpack_zip(file: File, sink: &mut Sink) -> Result<(), ArchiveError> {
    let corrupt = |e: zip::result::ZipError| ArchiveError::Corrupt(e.to_string());
    let mut archive = zip::ZipArchive::new(BufReader::new(file)).map_err(corrupt)?;
    for i in 0..archive.len() {
        let mut member = archive.by_index(i).map_err(corrupt)?;
        let name = String::from_utf8_lossy(member.name_raw()).into_owned();
        let kind = if member.is_symlink() {
            Member::Refused("links are not accepted")
        } else if member.is_dir() {
            Member::Dir
        } else {
            Member::File
        };
        sink.member(&name, kind, &mut member)?;
    }
    Ok(())
}

/// Unpack `archive` into the folder `dest` (which must exist), within `limits`.
pub fn unpack(
    archive: &Path,
    dest: &Path,
    limits: ArchiveLimits,
) -> Result<Unpacked, ArchiveError> {
    let mut file = File::open(archive).map_err(|source| ArchiveError::Io {
        path: archive.display().to_string(),
        source,
    })?;
    let mut sink = Sink {
        dest,
        limits,
        members: 0,
        unpacked: Unpacked::default(),
    };
    match sniff(&mut file)? {
        Format::Tar => unpack_tar(BufReader::new(file), &mut sink)?,
        Format::TarGz => unpack_tar(
            flate2::read::GzDecoder::new(BufReader::new(file)),
            &mut sink,
        )?,
        Format::Zip => unpack_zip(file, &mut sink)?,
    }
    Ok(sink.unpacked)
}

/// Write a gzip-compressed tar to `out` (`.tar`, uncompressed, when `out` ends so):
/// `manifest` as `manifest.csv` at the root, then `members` (archive path, file to read).
/// The archive is written beside `out` and renamed into place when complete.
pub fn pack(manifest: &[u8], members: &[(String, PathBuf)], out: &Path) -> io::Result<()> {
    let gzip = out.extension().is_none_or(|e| e != "tar");
    let tmp = out.with_extension("partial");
    let result = (|| {
        let file = io::BufWriter::new(File::create(&tmp)?);
        let mut sink: Box<dyn Write> = if gzip {
            Box::new(flate2::write::GzEncoder::new(
                file,
                flate2::Compression::default(),
            ))
        } else {
            Box::new(file)
        };
        {
            let mut builder = tar::Builder::new(&mut sink);
            builder.mode(tar::HeaderMode::Deterministic);
            let mut header = tar::Header::new_gnu();
            header.set_size(manifest.len() as u64);
            header.set_mode(0o644);
            builder.append_data(&mut header, "manifest.csv", manifest)?;
            for (name, path) in members {
                builder.append_path_with_name(path, name)?;
            }
            builder.finish()?;
        }
        sink.flush()?;
        drop(sink);
        std::fs::rename(&tmp, out)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("archive-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    const LIMITS: ArchiveLimits = ArchiveLimits {
        members: 100,
        unpacked_bytes: 1 << 20,
    };

    /// A tar whose headers are written by hand, so that hostile names and kinds can be made.
    fn raw_tar(members: &[(&str, tar::EntryType, &[u8])]) -> Vec<u8> {
        let mut builder = tar::Builder::new(Vec::new());
        for (name, kind, data) in members {
            let mut header = tar::Header::new_gnu();
            header.set_entry_type(*kind);
            header.set_size(data.len() as u64);
            header.set_mode(0o644);
            let bytes = name.as_bytes();
            header.as_old_mut().name[..bytes.len()].copy_from_slice(bytes);
            if *kind == tar::EntryType::Symlink {
                header.set_link_name("/etc/passwd").unwrap();
            }
            header.set_cksum();
            builder.append(&header, *data).unwrap();
        }
        builder.into_inner().unwrap()
    }

    #[test]
    fn member_names_that_leave_the_folder_are_refused() {
        assert_eq!(member_path("./a/b.png"), Ok("a/b.png".into()));
        assert_eq!(member_path("a//b.png"), Ok("a/b.png".into()));
        for bad in [
            "/etc/passwd",
            "../x",
            "a/../../x",
            "a/..",
            "C:/x",
            "a\\..\\x",
            "",
            "./",
        ] {
            assert!(member_path(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn hostile_members_are_refused_and_nothing_leaves_the_folder() {
        use tar::EntryType as T;
        let dir = temp("hostile");
        let dest = dir.join("out");
        std::fs::create_dir_all(&dest).unwrap();
        let bytes = raw_tar(&[
            ("ok/a.txt", T::Regular, b"a"),
            ("../escape.txt", T::Regular, b"x"),
            ("/tmp/abs.txt", T::Regular, b"x"),
            ("link", T::Symlink, b""),
            ("ok/a.txt", T::Regular, b"again"),
            ("fifo", T::Fifo, b""),
        ]);
        let archive = dir.join("a.tar");
        std::fs::write(&archive, bytes).unwrap();
        let unpacked = unpack(&archive, &dest, LIMITS).unwrap();
        assert_eq!(unpacked.files.iter().collect::<Vec<_>>(), ["ok/a.txt"]);
        assert_eq!(std::fs::read(dest.join("ok/a.txt")).unwrap(), b"a");
        let refused: Vec<&str> = unpacked.refused.iter().map(|r| r.path.as_str()).collect();
        assert_eq!(
            refused,
            ["../escape.txt", "/tmp/abs.txt", "link", "ok/a.txt", "fifo"]
        );
        assert!(unpacked.refused[2].reason.contains("links"));
        assert!(!dir.join("escape.txt").exists() && !dest.join("link").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn limits_end_the_unpacking_with_the_limit_named() {
        let dir = temp("limits");
        let files: Vec<(String, PathBuf)> = (0..5)
            .map(|i| {
                let path = dir.join(format!("f{i}"));
                std::fs::write(&path, vec![0u8; 1000]).unwrap();
                (format!("d/f{i}"), path)
            })
            .collect();
        let archive = dir.join("a.tar.gz");
        pack(b"path\n", &files, &archive).unwrap();
        let run = |limits: ArchiveLimits| {
            let dest = dir.join("out");
            let _ = std::fs::remove_dir_all(&dest);
            std::fs::create_dir_all(&dest).unwrap();
            unpack(&archive, &dest, limits)
        };
        let all = run(LIMITS).unwrap();
        assert_eq!((all.files.len(), all.bytes), (6, 5005));
        let few = run(ArchiveLimits {
            members: 3,
            ..LIMITS
        })
        .unwrap_err();
        assert!(few.to_string().contains("more than 3 members"), "{few}");
        // The zeros compress a hundredfold: the bytes are counted as written.
        let small = run(ArchiveLimits {
            unpacked_bytes: 5004,
            ..LIMITS
        })
        .unwrap_err();
        assert!(
            small.to_string().contains("more than 5004 bytes"),
            "{small}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn tar_and_zip_round_trip_and_other_files_are_refused() {
        let dir = temp("formats");
        let source = dir.join("a.txt");
        std::fs::write(&source, b"hello").unwrap();
        let members = [("x/a.txt".to_string(), source.clone())];
        for name in ["a.tar", "a.tar.gz"] {
            let archive = dir.join(name);
            pack(b"path\nx/a.txt\n", &members, &archive).unwrap();
            let dest = dir.join(format!("{name}.out"));
            std::fs::create_dir_all(&dest).unwrap();
            let unpacked = unpack(&archive, &dest, LIMITS).unwrap();
            assert_eq!(unpacked.files.len(), 2, "{name}");
            assert_eq!(
                std::fs::read(dest.join("manifest.csv")).unwrap(),
                b"path\nx/a.txt\n"
            );
            assert_eq!(std::fs::read(dest.join("x/a.txt")).unwrap(), b"hello");
        }
        let zip_path = dir.join("a.zip");
        {
            let mut writer = zip::ZipWriter::new(File::create(&zip_path).unwrap());
            let options = zip::write::SimpleFileOptions::default();
            writer.start_file("z/b.txt", options).unwrap();
            writer.write_all(b"zipped").unwrap();
            writer.start_file("../evil.txt", options).unwrap();
            writer.write_all(b"x").unwrap();
            writer.finish().unwrap();
        }
        let dest = dir.join("zip.out");
        std::fs::create_dir_all(&dest).unwrap();
        let unpacked = unpack(&zip_path, &dest, LIMITS).unwrap();
        assert_eq!(std::fs::read(dest.join("z/b.txt")).unwrap(), b"zipped");
        assert_eq!(unpacked.refused.len(), 1);
        assert!(!dir.join("evil.txt").exists());
        assert!(matches!(
            unpack(&source, &dest, LIMITS),
            Err(ArchiveError::UnknownFormat)
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
