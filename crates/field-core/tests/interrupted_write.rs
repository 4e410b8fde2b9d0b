//! `remove_unfinished_writes`, in a test binary of its own: it removes the temporary files of
//! every atomic write in progress in the process, which would fail other tests' writes.

use std::fs;

use zeroset_field_core::io::{remove_unfinished_writes, write_atomic};

#[test]
fn an_interrupt_removes_the_unfinished_write_and_keeps_the_old_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.ply");
    fs::write(&path, "old contents\n").unwrap();
    let hidden = || {
        fs::read_dir(dir.path())
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with('.')
            })
            .count()
    };
    let e = write_atomic(&path, |w| {
        w.write_all(b"half of the new")?;
        assert_eq!(hidden(), 1, "the write's temporary file");
        // What the CLI's Ctrl-C handler does before it exits.
        remove_unfinished_writes();
        assert_eq!(hidden(), 0, "the temporary file is still there");
        w.write_all(b" and the rest")
    })
    .unwrap_err();
    assert!(e.to_string().contains("mesh.ply"), "{e}");
    assert_eq!(fs::read_to_string(&path).unwrap(), "old contents\n");
    // Finished writes are off the list: nothing of theirs is touched.
    write_atomic(&path, |w| w.write_all(b"new contents\n")).unwrap();
    remove_unfinished_writes();
    assert_eq!(fs::read_to_string(&path).unwrap(), "new contents\n");
    assert_eq!(hidden(), 0);
}
