//! The crate's layers: `src/lib.rs` lists the modules in one order (its "Layers" table), and
//! each module may use only the modules listed before it. This reads the source and checks
//! both that the table matches the tree and that no `crate::` path reaches up.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// The modules of the layer table, in order.
fn layer_order() -> Vec<String> {
    let lib = std::fs::read_to_string(src().join("lib.rs")).unwrap();
    lib.lines()
        .filter_map(|l| l.strip_prefix("//! | "))
        .filter_map(|row| {
            let cells: Vec<&str> = row.split('|').map(str::trim).collect();
            let first = cells.first()?;
            first.parse::<u32>().ok()?;
            // `name`, [`name`] or [`name`](target): the link text.
            let cell = cells.get(1)?;
            let name = cell.split("](").next()?.trim_matches(|c| "[]`".contains(c));
            Some(name.to_string())
        })
        .collect()
}

/// Every `.rs` file under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The top-level modules a piece of source names through `crate::` (comments left out).
fn crate_paths(source: &str) -> BTreeSet<String> {
    let mut used = BTreeSet::new();
    for line in source.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + "crate::".len()..];
            if let Some(list) = rest.strip_prefix('{') {
                // `crate::{a::b, c}`: the first identifier of every item at the top level.
                let mut depth = 0;
                let mut start = true;
                for (k, c) in list.char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' if depth == 0 => {
                            rest = &list[k..];
                            break;
                        }
                        '}' => depth -= 1,
                        ',' if depth == 0 => start = true,
                        c if start && (c.is_alphanumeric() || c == '_') => {
                            let name: String = list[k..]
                                .chars()
                                .take_while(|c| c.is_alphanumeric() || *c == '_')
                                .collect();
                            used.insert(name);
                            start = false;
                        }
                        _ => {}
                    }
                }
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                used.insert(name);
            }
        }
    }
    used
}

#[test]
fn the_layer_table_matches_the_tree() {
    let order: BTreeSet<String> = layer_order().into_iter().collect();
    let mut tree = BTreeSet::new();
    for entry in std::fs::read_dir(src()).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        if name != "lib" {
            tree.insert(name);
        }
    }
    assert_eq!(order, tree, "src/lib.rs's layer table and src/ disagree");
}

#[test]
fn modules_use_only_modules_listed_before_them() {
    let order = layer_order();
    let rank = |m: &str| order.iter().position(|o| o == m);
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut violations = Vec::new();
    for file in files {
        let relative = file.strip_prefix(src()).unwrap();
        let top = relative
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy()
            .trim_end_matches(".rs")
            .to_string();
        if top == "lib" {
            continue;
        }
        let own = rank(&top).unwrap_or_else(|| panic!("{top} is not in the layer table"));
        let source = std::fs::read_to_string(&file).unwrap();
        for used in crate_paths(&source) {
            match rank(&used) {
                Some(r) if r > own => violations.push(format!(
                    "{} uses crate::{used}, which is listed after {top}",
                    relative.display()
                )),
                // Root re-exports (`crate::BakeError`, `crate::Result`) name lower modules.
                _ => {}
            }
        }
    }
    assert!(violations.is_empty(), "{}", violations.join("\n"));
}

/// The checker sees both path forms, and ignores comments.
#[test]
fn the_checker_reads_paths_and_lists() {
    let used = crate_paths(
        "use crate::a::b;\nuse crate::{c::d, e, f::{g, h}};\n// crate::z\nlet x = crate::y::f(); // crate::w",
    );
    let want: BTreeSet<String> = ["a", "c", "e", "f", "y"].map(String::from).into();
    assert_eq!(used, want);
}
