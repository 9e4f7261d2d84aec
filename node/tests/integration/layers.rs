//! The node crate's layers hold: every `crate::` path in `node/src` (outside comments) names
//! a module of a lower layer than the file's own, as the table in `docs/architecture.md`
//! ("Inside `node`: layers") says, and every module `lib.rs` declares has a layer there.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Module name to layer, read from the table between the doc's markers.
fn layers() -> BTreeMap<String, u32> {
    let doc = std::fs::read_to_string(Path::new(ROOT).join("../docs/architecture.md")).unwrap();
    let table = doc
        .split("<!-- BEGIN LAYERS -->")
        .nth(1)
        .and_then(|rest| rest.split("<!-- END LAYERS -->").next())
        .expect("docs/architecture.md has the layer table between its markers");
    let mut layers = BTreeMap::new();
    for row in table.lines().filter(|l| l.starts_with('|')) {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let Ok(layer) = cells[1].parse::<u32>() else {
            continue;
        };
        for module in cells[2].split(',') {
            let module = module.trim().trim_matches('`').to_string();
            assert!(
                layers.insert(module.clone(), layer).is_none(),
                "`{module}` has two rows in the layer table"
            );
        }
    }
    assert!(
        layers.len() > 10,
        "the layer table was not read: {layers:?}"
    );
    layers
}

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, found: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, found);
        } else if path.extension().is_some_and(|e| e == "rs") {
            found.push(path);
        }
    }
}

/// The modules `text` names as `crate::<module>`, with their line numbers, outside comments.
fn crate_paths(text: &str) -> Vec<(usize, String)> {
    let mut paths = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            let before = rest[..at].chars().last();
            rest = &rest[at + "crate::".len()..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$') {
                continue;
            }
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                paths.push((n + 1, name));
            }
        }
    }
    paths
}

#[test]
fn no_module_of_the_node_uses_a_layer_above_or_beside_its_own() {
    let layers = layers();
    let src = Path::new(ROOT).join("src");
    let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
    for line in lib.lines().map(str::trim) {
        let declared = line
            .strip_prefix("pub mod ")
            .or_else(|| line.strip_prefix("mod "))
            .and_then(|m| m.strip_suffix(';'));
        if let Some(module) = declared {
            assert!(
                layers.contains_key(module),
                "lib.rs declares `{module}`, which the layer table in docs/architecture.md does not name"
            );
        }
    }
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut broken = Vec::new();
    let mut checked = 0;
    for file in &files {
        let relative = file.strip_prefix(&src).unwrap();
        let top = relative.components().next().unwrap().as_os_str();
        let top = top.to_string_lossy().trim_end_matches(".rs").to_string();
        if top == "lib" || top == "main" {
            continue;
        }
        let own = *layers
            .get(&top)
            .unwrap_or_else(|| panic!("{} is in no layer", relative.display()));
        let text = std::fs::read_to_string(file).unwrap();
        for (line, used) in crate_paths(&text) {
            checked += 1;
            if used == top {
                continue;
            }
            let Some(&theirs) = layers.get(&used) else {
                broken.push(format!(
                    "{}:{line}: `crate::{used}` is in no layer",
                    relative.display()
                ));
                continue;
            };
            if theirs >= own {
                broken.push(format!(
                    "{}:{line}: `{top}` (layer {own}) uses `{used}` (layer {theirs})",
                    relative.display()
                ));
            }
        }
    }
    assert!(checked > 300, "only {checked} crate paths were read");
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

#[test]
fn crate_paths_are_read_from_code_not_comments_or_longer_names() {
    let text =
        "use crate::fusion::X; // crate::view\n/// [`crate::cli`]\nlet a = my_crate::bench;\n";
    assert_eq!(crate_paths(text), vec![(1, "fusion".to_string())]);
}
