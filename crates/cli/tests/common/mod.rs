//! What the command-line tests share: the shipped sample and a way to run the binary.
#![allow(dead_code)] // each test file uses some of these

use std::ffi::OsStr;
use std::path::PathBuf;
use std::process::{Command, Output};

/// The shipped sample, `samples/bunny_2k.xyzn` (2,000 oriented points).
pub fn sample() -> PathBuf {
    let path = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../samples/bunny_2k.xyzn"
    ));
    assert!(path.is_file(), "sample {} not found", path.display());
    path
}

/// Runs the binary with its operator disk cache off (the tests never write to the user's
/// cache) and no memory cap of the user's.
pub fn zeroset<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> Output {
    zeroset_with(args, &[])
}

/// Runs the binary with the environment variables `env` set over the defaults of
/// [`zeroset`] (`ZEROSET_CACHE_DIR` empty: no disk cache).
pub fn zeroset_with<S: AsRef<OsStr>>(
    args: impl IntoIterator<Item = S>,
    env: &[(&str, &OsStr)],
) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_zeroset"));
    // The user's memory cap is not the tests'.
    command
        .args(args)
        .env("ZEROSET_CACHE_DIR", "")
        .env_remove("ZEROSET_MEMORY_LIMIT");
    for (name, value) in env {
        command.env(name, value);
    }
    command.output().expect("cannot run the zeroset binary")
}

pub mod studio;
