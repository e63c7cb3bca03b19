//! The documentation the doc tests read.

use std::path::{Path, PathBuf};

/// The repository's root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The README and every page of docs/, in that order (docs/ by name).
pub fn pages() -> Vec<PathBuf> {
    let root = repo();
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    std::iter::once(root.join("README.md"))
        .chain(docs)
        .collect()
}

/// A doc's file name (for messages) and its text.
pub fn named_text(path: &Path) -> (String, String) {
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    (name, std::fs::read_to_string(path).unwrap())
}
