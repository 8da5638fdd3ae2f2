//! Helpers shared by the integration tests: the command line's, the servers' ([`server`]), and
//! the image encoders and fixtures every package's tests share ([`images`]).
#![allow(dead_code)]

/// Fail with the command's standard error unless it exited with success.
#[track_caller]
pub fn assert_success(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The README's sphere (`tests/fixtures/features/sphere_rgb8.png`) as command-line flags:
/// its white reference and its circle.
pub const README_SPHERE_FLAGS: [&str; 8] = [
    "--white", "0.8", "--cx", "96.5", "--cy", "94.25", "--r", "85",
];

mod images;
pub use images::*;

pub mod server;
