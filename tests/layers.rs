//! Arrows point down (issue 29 item 3): each folder under `src/` is a layer that imports only the
//! layers below it, in ARCHITECTURE.md's order
//!   cli, app > study > engine > scene > passes > gpu > volume > analysis > reference >
//!   model, files.
//! This reads every `crate::LAYER` path in `src/` and fails on one that runs back up.
//!
//! The imports that ran up when this check was written are listed in [`KNOWN`] (issue 29 moves
//! them); the list may only shrink: a new upward import fails, and so does an entry that no
//! longer occurs (delete it, so it cannot come back unnoticed).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The layers, top first; cli and app share the top.
const LAYERS: [(&str, u8); 12] = [
    ("cli", 0),
    ("app", 0),
    ("study", 1),
    ("engine", 2),
    ("scene", 3),
    ("passes", 4),
    ("gpu", 5),
    ("volume", 6),
    ("analysis", 7),
    ("reference", 8),
    ("model", 9),
    ("files", 9),
];

/// Upward imports at the time of writing: (file, layer it imports).
const KNOWN: [(&str, &str); 10] = [
    ("src/reference/brain_tests.rs", "analysis"),
    ("src/reference/raymarch/tests.rs", "passes"),
    ("src/reference/raymarch/dvr_sample.rs", "scene"),
    ("src/reference/raymarch/formulas.rs", "scene"),
    ("src/reference/raymarch/lighting.rs", "scene"),
    ("src/reference/raymarch/long_steps.rs", "scene"),
    ("src/reference/raymarch/mod.rs", "scene"),
    ("src/reference/raymarch/sampling.rs", "scene"),
    ("src/reference/raymarch/tests.rs", "scene"),
    ("src/reference/derivatives.rs", "volume"),
];

fn rank(layer: &str) -> Option<u8> {
    LAYERS.iter().find(|(l, _)| *l == layer).map(|(_, r)| *r)
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The layers `text` names as `crate::LAYER` (also inside `crate::{a, b}` groups).
fn imported_layers(text: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for (i, _) in text.match_indices("crate::") {
        let rest = &text[i + "crate::".len()..];
        let names: Vec<&str> = match rest.strip_prefix('{') {
            Some(group) => group
                .split('}')
                .next()
                .unwrap_or("")
                .split(',')
                .map(str::trim)
                .collect(),
            None => vec![rest],
        };
        for name in names {
            let word: String = name
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            found.insert(word);
        }
    }
    found
}

#[test]
fn no_import_runs_back_up_a_layer() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&root.join("src"), &mut files);
    let known: BTreeSet<(String, String)> = KNOWN
        .iter()
        .map(|(f, l)| (f.to_string(), l.to_string()))
        .collect();
    let mut upward = BTreeSet::new();
    for file in &files {
        let relative = file
            .strip_prefix(root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let Some(from) = relative.split('/').nth(1).and_then(rank) else {
            continue;
        };
        let text = std::fs::read_to_string(file).unwrap();
        for layer in imported_layers(&text) {
            if rank(&layer).is_some_and(|to| to < from) {
                upward.insert((relative.clone(), layer));
            }
        }
    }
    let new: Vec<_> = upward.difference(&known).collect();
    assert!(
        new.is_empty(),
        "imports that run back up a layer (move the code down, or the data into a lower \
         layer; ARCHITECTURE.md): {new:?}"
    );
    let gone: Vec<_> = known.difference(&upward).collect();
    assert!(
        gone.is_empty(),
        "these upward imports are gone: delete them from KNOWN in tests/layers.rs: {gone:?}"
    );
}

#[test]
fn grouped_imports_are_read() {
    let layers = imported_layers("use crate::{scene::Camera, passes::slice};\nuse crate::gpu::X;");
    assert!(
        ["scene", "passes", "gpu"]
            .iter()
            .all(|l| layers.contains(*l)),
        "{layers:?}"
    );
}
