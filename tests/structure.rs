//! The server crate's module structure, checked from its sources: top-level modules
//! depend one way (the layers below), and no two files import each other, directly or
//! round a longer circle. Cargo enforces the crate boundaries (`echogym-protocol` ←
//! `echogym-client`, `echogym`); this test enforces what Cargo cannot see inside a crate.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Top-level modules, lowest layer first: a module may use only modules listed before it.
const LAYERS: &[&str] = &[
    "sim",
    "recordings",
    "envs",
    "pool",
    "transport",
    "config",
    "daemon",
    "calibrate",
    "cli",
    "lib",
    "main",
];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
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

/// The code of a file without comments (doc comments name modules without using them).
fn code(path: &Path) -> String {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|line| line.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The directory whose files are the children of module file `file`.
fn children_dir(file: &Path) -> PathBuf {
    let stem = file.file_stem().unwrap().to_str().unwrap();
    if stem == "mod" || stem == "lib" {
        file.parent().unwrap().to_path_buf()
    } else {
        file.with_extension("")
    }
}

/// The deepest module file reached by following `segments` from the module in `dir`.
fn resolve(mut dir: PathBuf, segments: &[&str]) -> Option<PathBuf> {
    let mut found = None;
    for segment in segments {
        let file = dir.join(format!("{segment}.rs"));
        let module = dir.join(segment).join("mod.rs");
        if file.is_file() {
            found = Some(file);
        } else if module.is_file() {
            found = Some(module);
        } else {
            break;
        }
        dir = children_dir(found.as_ref().unwrap());
    }
    found
}

/// Paths `crate::a::b` / `super::a::b` used in `text`, as (root, segments); a brace
/// group `super::{a::X, b}` yields one path per member.
fn paths(text: &str) -> Vec<(String, Vec<String>)> {
    let mut out = Vec::new();
    for root in ["crate", "super"] {
        let pattern = format!("{root}::");
        let mut rest = text;
        while let Some(at) = rest.find(&pattern) {
            let before = rest[..at].chars().last();
            rest = &rest[at + pattern.len()..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue; // `super::super::` is followed from its first `super`
            }
            let mut supers = 0;
            while let Some(next) = rest.strip_prefix("super::") {
                supers += 1;
                rest = next;
            }
            let members: Vec<String> = if let Some(group) = rest.strip_prefix('{') {
                let end = group.find('}').unwrap_or(group.len());
                group[..end]
                    .split(',')
                    .map(|m| m.trim().to_owned())
                    .collect()
            } else {
                vec![
                    rest.chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                        .collect(),
                ]
            };
            for member in members {
                let mut segments = vec!["super".to_owned(); supers];
                segments.extend(
                    member
                        .split("::")
                        .filter(|s| !s.is_empty())
                        .map(str::to_owned),
                );
                out.push((root.to_owned(), segments));
            }
        }
    }
    out
}

/// Which files each file imports (module hubs `mod.rs`/`lib.rs` left out: they
/// re-export their children, so every child would seem to depend on its siblings).
fn file_graph() -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let root = src();
    let mut files = Vec::new();
    rust_files(&root, &mut files);
    let mut graph = BTreeMap::new();
    for file in &files {
        let mut targets = BTreeSet::new();
        for (kind, segments) in paths(&code(file)) {
            let mut dir = if kind == "crate" {
                root.clone()
            } else {
                // `super` of a file is the module that declares it.
                let own = children_dir(file);
                own.parent().unwrap().to_path_buf()
            };
            let mut rest: &[String] = &segments;
            while rest.first().is_some_and(|s| s == "super") {
                dir = dir.parent().unwrap().to_path_buf();
                rest = &rest[1..];
            }
            let segments: Vec<&str> = rest.iter().map(String::as_str).collect();
            if let Some(target) = resolve(dir, &segments) {
                let hub = matches!(
                    target.file_name().unwrap().to_str(),
                    Some("mod.rs" | "lib.rs")
                );
                if !hub && &target != file {
                    targets.insert(target);
                }
            }
        }
        graph.insert(file.clone(), targets);
    }
    graph
}

fn top_module(file: &Path) -> String {
    let rel = file.strip_prefix(src()).unwrap();
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_str()
        .unwrap();
    first.trim_end_matches(".rs").to_owned()
}

#[test]
fn top_level_modules_depend_one_way() {
    let mut wrong = Vec::new();
    let root = src();
    let mut files = Vec::new();
    rust_files(&root, &mut files);
    for file in &files {
        let from = top_module(file);
        let Some(from_layer) = LAYERS.iter().position(|l| *l == from) else {
            wrong.push(format!("{from} is not in LAYERS: place it"));
            continue;
        };
        for (kind, segments) in paths(&code(file)) {
            let Some(to) = segments.first().filter(|_| kind == "crate") else {
                continue;
            };
            if let Some(to_layer) = LAYERS.iter().position(|l| l == to)
                && to_layer > from_layer
            {
                wrong.push(format!(
                    "{} uses crate::{to} (a layer above {from})",
                    file.strip_prefix(&root).unwrap().display()
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "upward imports:\n{}", wrong.join("\n"));
}

/// Every circle depth-first search closes in `graph` (a grey node reached again).
fn find_circles(graph: &BTreeMap<PathBuf, BTreeSet<PathBuf>>) -> Vec<String> {
    #[derive(Clone, Copy, PartialEq)]
    enum Colour {
        White,
        Grey,
        Black,
    }
    fn visit<'a>(
        node: &'a PathBuf,
        graph: &'a BTreeMap<PathBuf, BTreeSet<PathBuf>>,
        colour: &mut BTreeMap<&'a PathBuf, Colour>,
        stack: &mut Vec<&'a PathBuf>,
        circles: &mut Vec<String>,
    ) {
        colour.insert(node, Colour::Grey);
        stack.push(node);
        for next in &graph[node] {
            match colour[next] {
                Colour::White => visit(next, graph, colour, stack, circles),
                Colour::Grey => {
                    let start = stack.iter().position(|n| *n == next).unwrap();
                    let names: Vec<String> = stack[start..]
                        .iter()
                        .chain(std::iter::once(&next))
                        .map(|p| p.display().to_string())
                        .collect();
                    circles.push(names.join(" → "));
                }
                Colour::Black => {}
            }
        }
        stack.pop();
        colour.insert(node, Colour::Black);
    }
    let mut colour: BTreeMap<&PathBuf, Colour> = graph.keys().map(|k| (k, Colour::White)).collect();
    let mut circles = Vec::new();
    for node in graph.keys() {
        if colour[node] == Colour::White {
            visit(node, graph, &mut colour, &mut Vec::new(), &mut circles);
        }
    }
    circles
}

#[test]
fn no_file_imports_round_a_circle() {
    let graph = file_graph();
    assert!(
        graph.values().map(BTreeSet::len).sum::<usize>() > 100,
        "the import scan found too few imports to mean anything"
    );
    let circles = find_circles(&graph);
    assert!(
        circles.is_empty(),
        "import circles:\n{}",
        circles.join("\n")
    );
}

#[test]
fn the_checks_themselves_work() {
    // Both forms of import are found and resolved, and a circle is seen.
    let found =
        paths("use super::{factory::EnvFactory, null::X};\nlet a = crate::envs::registry::f();");
    assert!(found.contains(&("super".into(), vec!["factory".into(), "EnvFactory".into()])));
    assert!(found.contains(&("super".into(), vec!["null".into(), "X".into()])));
    assert!(found.contains(&(
        "crate".into(),
        vec!["envs".into(), "registry".into(), "f".into()]
    )));
    let registry = resolve(src(), &["envs", "registry", "EnvRegistry"]).unwrap();
    assert!(registry.ends_with("envs/registry.rs"));
    let graph: BTreeMap<PathBuf, BTreeSet<PathBuf>> = [
        ("a", vec!["b"]),
        ("b", vec!["c"]),
        ("c", vec!["a"]),
        ("d", vec![]),
    ]
    .into_iter()
    .map(|(k, v)| (k.into(), v.into_iter().map(PathBuf::from).collect()))
    .collect();
    assert_eq!(find_circles(&graph), vec!["a → b → c → a".to_owned()]);
}
