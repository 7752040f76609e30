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

/// The sibling modules a file in folder `folder` (its path under `src/`, e.g. `radiosity`)
/// names: through `super::name` and through `crate::folder::name` (comments left out).
fn sibling_paths(source: &str, folder: &str, siblings: &BTreeSet<String>) -> BTreeSet<String> {
    let mut used = BTreeSet::new();
    let prefixes = [
        "super::".to_string(),
        format!("crate::{}::", folder.replace('/', "::")),
    ];
    for line in source.lines() {
        let code = line.split("//").next().unwrap_or("");
        for prefix in &prefixes {
            let mut rest = code;
            while let Some(i) = rest.find(prefix.as_str()) {
                rest = &rest[i + prefix.len()..];
                let names: Vec<String> = match rest.strip_prefix('{') {
                    Some(list) => {
                        let end = list.find('}').unwrap_or(list.len());
                        list[..end]
                            .split(',')
                            .map(|item| {
                                item.trim()
                                    .chars()
                                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                                    .collect()
                            })
                            .collect()
                    }
                    None => vec![
                        rest.chars()
                            .take_while(|c| c.is_alphanumeric() || *c == '_')
                            .collect(),
                    ],
                };
                used.extend(names.into_iter().filter(|n| siblings.contains(n)));
            }
        }
    }
    used
}

/// A cycle in `graph` (each node's edges), as the nodes along it; `None` when it has none.
fn find_cycle(graph: &std::collections::BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &std::collections::BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(i) = path.iter().position(|p| p == node) {
            let mut cycle = path[i..].to_vec();
            cycle.push(node.to_string());
            return Some(cycle);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(c) = visit(next, graph, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|k| visit(k, graph, &mut Vec::new(), &mut done))
}

/// Inside every folder, the files that use each other through `super::` (or the folder's
/// own `crate::` path) form no circle: each folder's files stack up as the crate's modules do.
#[test]
fn files_inside_a_folder_use_each_other_without_a_circle() {
    let mut folders = Vec::new();
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                out.push(path.clone());
                walk(&path, out);
            }
        }
    }
    walk(&src(), &mut folders);
    let mut circles = Vec::new();
    for folder in folders {
        let name = folder
            .strip_prefix(src())
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let mut files = Vec::new();
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
            if stem != "mod" {
                files.push((stem, path));
            }
        }
        let siblings: BTreeSet<String> = files.iter().map(|(s, _)| s.clone()).collect();
        let mut graph = std::collections::BTreeMap::new();
        for (stem, path) in &files {
            let mut sources = Vec::new();
            if path.is_dir() {
                rust_files(path, &mut sources);
            } else {
                sources.push(path.clone());
            }
            let mut used = BTreeSet::new();
            for file in sources {
                let source = std::fs::read_to_string(&file).unwrap();
                // A file in a sub-folder reaches the folder's siblings through
                // `super::super::`; count those as the sub-folder's own.
                let source = if file.parent() == Some(folder.as_path()) {
                    source
                } else {
                    source.replace("super::super::", "super::")
                };
                used.extend(sibling_paths(&source, &name, &siblings));
            }
            used.remove(stem);
            graph.insert(stem.clone(), used);
        }
        if let Some(cycle) = find_cycle(&graph) {
            circles.push(format!("{name}: {}", cycle.join(" → ")));
        }
    }
    assert!(circles.is_empty(), "circles:\n{}", circles.join("\n"));
}

/// The folder checker reads both path forms and finds a circle of two.
#[test]
fn the_folder_checker_reads_paths_and_finds_circles() {
    let siblings: BTreeSet<String> = ["a", "b", "c"].map(String::from).into();
    let used = sibling_paths(
        "use super::a::X;\nuse super::{b, d};\n// super::c\nlet y = crate::f::c::g();",
        "f",
        &siblings,
    );
    assert_eq!(used, ["a", "b", "c"].map(String::from).into());
    let mut graph = std::collections::BTreeMap::new();
    graph.insert("a".to_string(), BTreeSet::from(["b".to_string()]));
    graph.insert("b".to_string(), BTreeSet::from(["a".to_string()]));
    assert!(find_cycle(&graph).is_some());
    graph.insert("b".to_string(), BTreeSet::new());
    assert!(find_cycle(&graph).is_none());
}

/// The Bevy plugin's modules (one per feature) use each other through `crate::` without a
/// circle. (Read from the source, so the core's tests need no Bevy.)
#[test]
fn the_plugin_modules_use_each_other_without_a_circle() {
    let plugin = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bevy_lightbake/src");
    let mut files = Vec::new();
    rust_files(&plugin, &mut files);
    let modules: BTreeSet<String> = files
        .iter()
        .map(|f| f.file_stem().unwrap().to_string_lossy().into_owned())
        .filter(|m| m != "lib")
        .collect();
    let mut graph = std::collections::BTreeMap::new();
    for file in &files {
        let module = file.file_stem().unwrap().to_string_lossy().into_owned();
        if module == "lib" {
            continue;
        }
        let source = std::fs::read_to_string(file).unwrap();
        let mut used: BTreeSet<String> = crate_paths(&source)
            .into_iter()
            .filter(|m| modules.contains(m) && *m != module)
            .collect();
        used.extend(graph.remove(&module).unwrap_or_default());
        graph.insert(module, used);
    }
    assert!(graph.len() > 5, "the plugin's modules were not found");
    if let Some(cycle) = find_cycle(&graph) {
        panic!("circle in bevy_lightbake: {}", cycle.join(" → "));
    }
}
