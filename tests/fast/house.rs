//! House rules on the source tree itself: no import cycle of any length (between files, or
//! between top-level modules such as `acquire` and `config`), every top-level module imports
//! only from the floors below its own (the floor list in README.md), `config` imports nothing
//! from the stream's runtime (`acquire`, `record`, `recorder`, `daemon`), and no function is
//! longer than the house allows (`.ci/fn-lengths`, exceptions in `.ci/long-functions.txt`).
//! Reads every `use` tree
//! and every inline `crate::`/`super::`/`rigmon_*::` path under `src/` and each workspace
//! crate's `crates/*/src/` (comments and string literals removed) as one tree (the `rigmon`
//! package's re-exports) and resolves each to the module file it names. The crate
//! boundaries themselves are the compiler's: a lower crate cannot name a higher one.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module as its path from the crate root (`["dsp", "speed"]`); the root is `[]`.
type Module = Vec<String>;

fn rs_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rs_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module a file defines: `a/b.rs` and `a/b/mod.rs` are `a::b`, `lib.rs` is the root.
fn module_of(rel: &Path) -> Module {
    let mut parts: Vec<String> = rel
        .with_extension("")
        .iter()
        .map(|c| c.to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|l| l == "mod") || parts == ["lib"] {
        parts.pop();
    }
    parts
}

/// Source text with comments, string and char literals blanked out (newlines kept).
fn code_only(src: &str) -> String {
    let c: Vec<char> = src.chars().collect();
    let mut out = String::with_capacity(src.len());
    let mut i = 0;
    let blank = |out: &mut String, ch: char| out.push(if ch == '\n' { '\n' } else { ' ' });
    while i < c.len() {
        let next = c.get(i + 1).copied();
        if c[i] == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if c[i] == '/' && next == Some('*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(&mut out, c[i]);
                    i += 1;
                }
            }
        } else if c[i] == 'r'
            && (next == Some('"') || next == Some('#'))
            && (i == 0 || !(c[i - 1].is_alphanumeric() || c[i - 1] == '_'))
        {
            // raw string r"..." or r#"..."#
            let mut j = i + 1;
            let mut hashes = 0;
            while c.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if c.get(j) != Some(&'"') {
                out.push(c[i]);
                i += 1;
                continue;
            }
            j += 1;
            'raw: while j < c.len() {
                if c[j] == '"' && (1..=hashes).all(|k| c.get(j + k) == Some(&'#')) {
                    j += 1 + hashes;
                    break 'raw;
                }
                blank(&mut out, c[j]);
                j += 1;
            }
            i = j;
        } else if c[i] == '"' {
            i += 1;
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    i += 1;
                }
                if i < c.len() {
                    blank(&mut out, c[i]);
                }
                i += 1;
            }
            i += 1;
        } else if c[i] == '\'' && next == Some('\\') {
            // escaped char literal '\n', '\'', '\u{..}'
            i += 2;
            while i < c.len() && c[i] != '\'' {
                i += 1;
            }
            i += 1;
        } else if c[i] == '\'' && c.get(i + 2) == Some(&'\'') {
            i += 3; // plain char literal; a lifetime has no closing quote
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

fn is_ident(ch: char) -> bool {
    ch.is_alphanumeric() || ch == '_'
}

/// Expand a `use` tree (`a::{b, c::{d, e}}`) into its paths; `as` renames dropped.
fn expand(tree: &str) -> Vec<String> {
    let mut t = String::new();
    let mut words = tree.split_whitespace();
    while let Some(w) = words.next() {
        if w == "as" {
            // drop the new name, keep the punctuation after it
            let renamed = words.next().unwrap_or("");
            t.push_str(renamed.trim_start_matches(is_ident));
        } else {
            t.push_str(w);
        }
    }
    expand_tree(&t)
}

fn expand_tree(t: &str) -> Vec<String> {
    let Some(open) = t.find('{') else {
        return vec![t.to_string()];
    };
    let mut depth = 0;
    let mut close = t.len();
    for (k, ch) in t.char_indices().skip(open) {
        match ch {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    close = k;
                    break;
                }
            }
            _ => {}
        }
    }
    let (pre, inner, post) = (
        &t[..open],
        &t[open + 1..close],
        &t[(close + 1).min(t.len())..],
    );
    let mut items = Vec::new();
    let (mut depth, mut start) = (0, 0);
    for (k, ch) in inner.char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&inner[start..k]);
                start = k + 1;
            }
            _ => {}
        }
    }
    items.push(&inner[start..]);
    items
        .into_iter()
        .filter(|it| !it.is_empty())
        .flat_map(|it| expand_tree(&format!("{pre}{it}{post}")))
        .collect()
}

/// Paths a file names, each with the (possibly inline) module it is written in.
fn paths_in(code: &str, file_module: &Module) -> Vec<(Module, String)> {
    let c: Vec<char> = code.chars().collect();
    let mut out = Vec::new();
    // inline `mod name {` blocks: (name, brace depth at which it closes)
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut pending_mod: Option<String> = None;
    let here = |inline: &Vec<(String, usize)>| {
        let mut m = file_module.clone();
        m.extend(inline.iter().map(|(n, _)| n.clone()));
        m
    };
    let word_at = |i: usize, w: &str| {
        let wc: Vec<char> = w.chars().collect();
        c.len() >= i + wc.len()
            && c[i..i + wc.len()] == wc[..]
            && (i == 0 || !is_ident(c[i - 1]))
            && !c.get(i + wc.len()).is_some_and(|&x| is_ident(x))
    };
    let mut i = 0;
    while i < c.len() {
        match c[i] {
            '{' => {
                depth += 1;
                if let Some(name) = pending_mod.take() {
                    inline.push((name, depth));
                }
                i += 1;
                continue;
            }
            '}' => {
                if inline.last().is_some_and(|(_, d)| *d == depth) {
                    inline.pop();
                }
                depth = depth.saturating_sub(1);
                i += 1;
                continue;
            }
            ';' => pending_mod = None,
            _ => {}
        }
        if word_at(i, "mod") {
            let rest: String = c[i + 3..].iter().take(80).collect();
            let name: String = rest
                .trim_start()
                .chars()
                .take_while(|&x| is_ident(x))
                .collect();
            pending_mod = Some(name);
            i += 3;
        } else if word_at(i, "use") {
            let end = (i..c.len()).find(|&k| c[k] == ';').unwrap_or(c.len());
            let tree: String = c[i + 3..end].iter().collect();
            for p in expand(&tree) {
                out.push((here(&inline), p));
            }
            i = end;
        } else if word_at(i, "crate") || word_at(i, "super") {
            let mut j = i;
            while j < c.len() && (is_ident(c[j]) || c[j] == ':') {
                j += 1;
            }
            let path: String = c[i..j].iter().collect();
            // a bare `crate` / `super` is a visibility (`pub(crate)`), not a path
            if path.contains("::") {
                out.push((here(&inline), path));
            }
            i = j;
        } else {
            i += 1;
        }
    }
    out
}

/// The module file a path names (longest known prefix), or `None` for an external crate.
fn resolve(
    from: &Module,
    path: &str,
    modules: &BTreeMap<Module, PathBuf>,
    dirs: &BTreeSet<Module>,
) -> Option<Module> {
    let segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
    let (mut full, rest): (Module, &[&str]) = match segs.first()? {
        &"crate" => (Vec::new(), &segs[1..]),
        &"super" | &"self" => {
            let mut base = from.clone();
            let mut k = 0;
            while k < segs.len() && (segs[k] == "super" || segs[k] == "self") {
                if segs[k] == "super" {
                    base.pop();
                }
                k += 1;
            }
            (base, &segs[k..])
        }
        first => {
            // `use child::X` inside a module directory's mod.rs
            let mut child = from.clone();
            child.push(first.to_string());
            if dirs.contains(from) && modules.contains_key(&child) {
                (from.clone(), &segs[..])
            } else {
                return None;
            }
        }
    };
    full.extend(rest.iter().map(|s| s.to_string()));
    (0..=full.len())
        .rev()
        .map(|k| full[..k].to_vec())
        .find(|m| modules.contains_key(m))
}

fn name(m: &Module) -> String {
    if m.is_empty() {
        "crate".into()
    } else {
        m.join("::")
    }
}

fn is_ancestor(a: &Module, b: &Module) -> bool {
    a.len() <= b.len() && b[..a.len()] == a[..]
}

struct Tree {
    /// (importer, imported) module pairs with the files that wrote the import.
    edges: BTreeMap<(Module, Module), BTreeSet<String>>,
}

/// Where the sources are: the `rigmon` package's own `src/` and each workspace crate's, with
/// the module path the crate's root has in the one tree the rules read (`rigmon`'s
/// re-exports: the core, runtime and lab modules at the top, the historian as `historian`).
const SOURCE_ROOTS: &[(&str, &str, &[&str])] = &[
    ("src", "rigmon", &[]),
    ("crates/core/src", "rigmon_core", &[]),
    ("crates/runtime/src", "rigmon_runtime", &[]),
    ("crates/lab/src", "rigmon_lab", &[]),
    ("crates/historian/src", "rigmon_historian", &["historian"]),
];

/// A file's text with the workspace's crate names written as the one tree's paths: a
/// historian file's `crate::x` is `crate::historian::x`, `rigmon_core::x` is `crate::x`.
fn as_one_tree(text: &str, prefix: &[&str]) -> String {
    let mut t = text.to_string();
    if !prefix.is_empty() {
        t = t.replace("crate::", &format!("crate::{}::", prefix.join("::")));
    }
    for (_, krate, pre) in SOURCE_ROOTS {
        let to = if pre.is_empty() {
            "crate::".to_string()
        } else {
            format!("crate::{}::", pre.join("::"))
        };
        t = t.replace(&format!("{krate}::"), &to);
    }
    t
}

fn read_tree() -> Tree {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut modules = BTreeMap::new();
    let mut dirs = BTreeSet::new();
    let mut files = Vec::new();
    for (dir, _, prefix) in SOURCE_ROOTS {
        let src = repo.join(dir);
        let mut found = Vec::new();
        rs_files(&src, &mut found);
        for f in found {
            let rel = f.strip_prefix(&src).unwrap().to_path_buf();
            if rel == Path::new("main.rs") || rel.starts_with("bin") {
                continue; // a binary is its own crate
            }
            let mut m: Module = prefix.iter().map(|s| s.to_string()).collect();
            m.extend(module_of(&rel));
            if rel.ends_with("mod.rs") || rel == Path::new("lib.rs") {
                dirs.insert(m.clone());
            }
            let shown = format!("{dir}/{}", rel.display());
            files.push((m.clone(), f.clone(), shown, *prefix));
            modules.insert(m, f);
        }
    }
    let mut edges: BTreeMap<(Module, Module), BTreeSet<String>> = BTreeMap::new();
    for (m, f, shown, prefix) in &files {
        let text = as_one_tree(&std::fs::read_to_string(f).unwrap(), prefix);
        for (from, p) in paths_in(&code_only(&text), m) {
            if let Some(t) = resolve(&from, &p, &modules, &dirs) {
                if &t != m {
                    edges
                        .entry((m.clone(), t))
                        .or_default()
                        .insert(format!("{shown}: {p}"));
                }
            }
        }
    }
    Tree { edges }
}

/// Every top-level module of the one tree (a file or a folder of a crate's `src/`), by name.
fn top_level_modules() -> BTreeSet<String> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = BTreeSet::new();
    for (dir, _, prefix) in SOURCE_ROOTS {
        if let Some(p) = prefix.first() {
            out.insert(p.to_string());
            continue;
        }
        for entry in std::fs::read_dir(repo.join(dir)).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_stem().unwrap().to_string_lossy().to_string();
            let is_module = path.is_dir() || path.extension().is_some_and(|e| e == "rs");
            if is_module && !["main", "lib", "bin"].contains(&name.as_str()) {
                out.insert(name);
            }
        }
    }
    out
}

/// The parser finds what it must: a known import is seen, so an empty result means something.
#[test]
fn the_import_reader_sees_known_imports() {
    let tree = read_tree();
    let has = |a: &str, b: &str| {
        let m = |s: &str| -> Module { s.split("::").map(String::from).collect() };
        tree.edges.contains_key(&(m(a), m(b)))
    };
    assert!(
        has("calibrate::views", "calibrate::modes"),
        "use super::modes"
    );
    assert!(has("model::onnx", "config"), "use crate::config::RigConfig");
    assert!(
        has("calibrate::modes", "calibrate::stats"),
        "inline super::stats::median"
    );
    assert_eq!(
        expand("super::{a, b::{C, d as D}}"),
        ["super::a", "super::b::C", "super::b::d"]
    );
    let visibility = paths_in("pub(crate) mod a;\npub(super) fn f() {}", &Vec::new());
    assert!(visibility.is_empty(), "{visibility:?}");
    let code = code_only("let s = \"crate::x\"; // crate::y\nlet c = '\"'; crate::z::w");
    assert!(
        !code.contains("crate::x") && !code.contains("crate::y") && code.contains("crate::z::w")
    );
}

/// Strongly connected components of a directed graph with more than one node (Tarjan):
/// every import cycle, whatever its length.
fn cycles<N: Ord + Clone>(edges: &BTreeMap<N, BTreeSet<N>>) -> Vec<Vec<N>> {
    struct Walk<'a, N: Ord> {
        edges: &'a BTreeMap<N, BTreeSet<N>>,
        index: BTreeMap<N, usize>,
        low: BTreeMap<N, usize>,
        stack: Vec<N>,
        on_stack: BTreeSet<N>,
        out: Vec<Vec<N>>,
    }
    fn visit<N: Ord + Clone>(w: &mut Walk<'_, N>, v: &N) {
        let i = w.index.len();
        w.index.insert(v.clone(), i);
        w.low.insert(v.clone(), i);
        w.stack.push(v.clone());
        w.on_stack.insert(v.clone());
        for t in w.edges.get(v).into_iter().flatten() {
            if !w.index.contains_key(t) {
                visit(w, t);
                let lt = w.low[t];
                let lv = w.low.get_mut(v).unwrap();
                *lv = (*lv).min(lt);
            } else if w.on_stack.contains(t) {
                let it = w.index[t];
                let lv = w.low.get_mut(v).unwrap();
                *lv = (*lv).min(it);
            }
        }
        if w.low[v] == w.index[v] {
            let mut comp = Vec::new();
            while let Some(x) = w.stack.pop() {
                w.on_stack.remove(&x);
                let done = &x == v;
                comp.push(x);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                w.out.push(comp);
            }
        }
    }
    let mut w = Walk {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in edges.keys() {
        if !w.index.contains_key(v) {
            visit(&mut w, v);
        }
    }
    w.out
}

/// One import of each pair inside a cycle, to say where it is written.
fn cycle_report(comp: &[Module], tree: &Tree, same: impl Fn(&Module, &Module) -> bool) -> String {
    let mut why = Vec::new();
    for ((a, b), w) in &tree.edges {
        let (ia, ib) = (
            comp.iter().find(|m| same(m, a)),
            comp.iter().find(|m| same(m, b)),
        );
        if let (Some(x), Some(y)) = (ia, ib) {
            if x != y {
                why.push(format!(
                    "  {} -> {}: {}",
                    name(x),
                    name(y),
                    w.iter().next().unwrap()
                ));
            }
        }
    }
    why.sort();
    why.dedup_by(|a, b| a.split(':').next() == b.split(':').next());
    format!(
        "{}\n{}",
        comp.iter().map(name).collect::<Vec<_>>().join(" -> "),
        why.join("\n")
    )
}

/// No import cycle of any length: neither between files (a module and its own parent, which
/// declares and re-exports it, excepted) nor between top-level modules. No exemptions.
#[test]
fn no_import_cycle_of_any_length() {
    let tree = read_tree();
    let mut files: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    let mut top: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (a, b) in tree.edges.keys() {
        if !is_ancestor(a, b) && !is_ancestor(b, a) {
            files.entry(a.clone()).or_default().insert(b.clone());
        }
        if let (Some(x), Some(y)) = (a.first(), b.first()) {
            if x != y {
                top.entry(vec![x.clone()])
                    .or_default()
                    .insert(vec![y.clone()]);
            }
        }
    }
    let mut found: Vec<String> = cycles(&files)
        .iter()
        .map(|c| format!("files: {}", cycle_report(c, &tree, |m, x| m == x)))
        .collect();
    found.extend(cycles(&top).iter().map(|c| {
        format!(
            "top level: {}",
            cycle_report(c, &tree, |m, x| x.first() == m.first())
        )
    }));
    assert!(
        found.is_empty(),
        "import cycles (move the shared item down into a module all of them may use):\n{}",
        found.join("\n")
    );
}

/// The cycle finder finds cycles longer than two, and none in a chain.
#[test]
fn the_cycle_finder_sees_long_cycles() {
    let g = |e: &[(u8, u8)]| {
        let mut m: BTreeMap<u8, BTreeSet<u8>> = BTreeMap::new();
        for (a, b) in e {
            m.entry(*a).or_default().insert(*b);
            m.entry(*b).or_default();
        }
        m
    };
    assert_eq!(
        cycles(&g(&[(1, 2), (2, 3), (3, 1), (3, 4)])),
        vec![vec![1, 2, 3]]
    );
    assert!(cycles(&g(&[(1, 2), (2, 3), (1, 3)])).is_empty());
    assert_eq!(
        cycles(&g(&[(1, 2), (2, 1), (3, 4), (4, 5), (5, 3)])).len(),
        2
    );
}

/// The floors the README states (section "Floors"): every top-level module is on one floor,
/// and it imports only from floors below its own.
#[test]
fn every_module_imports_only_from_lower_floors() {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let mut floor_of: BTreeMap<String, usize> = BTreeMap::new();
    for line in readme.lines() {
        let Some(rest) = line.strip_prefix("floor ") else {
            continue;
        };
        let (n, rest) = rest.split_once(' ').expect("floor N  a, b  what they do");
        let n: usize = n.parse().expect("floor number");
        let names = rest.trim_start().split("  ").next().unwrap();
        for m in names.split(',') {
            floor_of.insert(m.trim().to_string(), n);
        }
    }
    assert!(
        floor_of.len() > 10,
        "README.md must list the floors (lines `floor N  module, module  what they do`)"
    );
    let tree = read_tree();
    let mut missing: Vec<String> = top_level_modules()
        .into_iter()
        .filter(|m| !floor_of.contains_key(m))
        .collect();
    missing.sort();
    missing.dedup();
    assert!(
        missing.is_empty(),
        "top-level modules on no floor of README.md: {missing:?} (add each to its floor)"
    );
    let mut upward = Vec::new();
    for ((a, b), why) in &tree.edges {
        if let (Some(x), Some(y)) = (a.first(), b.first()) {
            if x != y && floor_of[x] <= floor_of[y] {
                upward.push(format!(
                    "{x} (floor {}) imports {y} (floor {}): {}",
                    floor_of[x],
                    floor_of[y],
                    why.iter().next().unwrap()
                ));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "imports from the same or a higher floor (move the item down, or the module up in README.md):\n{}",
        upward.join("\n")
    );
}

/// Configuration sits below the stream: `config` never imports acquisition, the recorder or
/// the daemon (each of those owns its config type and reads `config` instead).
#[test]
fn config_imports_nothing_from_the_stream_runtime() {
    let tree = read_tree();
    let banned = ["acquire", "record", "recorder", "daemon"];
    let found: Vec<String> = tree
        .edges
        .iter()
        .filter(|((a, b), _)| {
            a.first().is_some_and(|x| x == "config")
                && b.first().is_some_and(|y| banned.contains(&y.as_str()))
        })
        .flat_map(|(_, why)| why.iter().cloned())
        .collect();
    assert!(
        found.is_empty(),
        "src/config imports from acquire/record/recorder/daemon (move the type to its owner):\n{}",
        found.join("\n")
    );
}

/// No function under src/ is longer than 80 lines (100 in the daemon's event loop rule of
/// issue 17 is now the whole tree's 80), except those listed in `.ci/long-functions.txt`
/// with their length today; a listed function may only shrink, and leaves the list when it
/// fits. The same script CI runs (`.ci/fn-lengths src --max 80 --allow ...`).
#[test]
fn no_function_is_longer_than_the_house_allows() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::process::Command::new("python3")
        .arg(repo.join(".ci/fn-lengths"))
        .args([
            "src",
            "crates",
            "--max",
            "80",
            "--allow",
            ".ci/long-functions.txt",
        ])
        .current_dir(repo)
        .output()
        .expect("python3 runs .ci/fn-lengths; install python3");
    assert!(
        out.status.success(),
        ".ci/fn-lengths src crates --max 80 --allow .ci/long-functions.txt failed; split the functions it lists:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The vocabulary is the lowest floor: every module may import it, and it imports nothing
/// from the crate (its types name concepts; they know no room that uses them).
#[test]
fn vocabulary_imports_nothing_from_the_crate() {
    let tree = read_tree();
    let found: Vec<String> = tree
        .edges
        .iter()
        .filter(|((a, b), _)| {
            a.first().is_some_and(|x| x == "vocabulary")
                && b.first().is_none_or(|y| y != "vocabulary")
        })
        .flat_map(|(_, why)| why.iter().cloned())
        .collect();
    assert!(
        found.is_empty(),
        "src/vocabulary imports from the rest of the crate (it must stay a leaf):\n{}",
        found.join("\n")
    );
    let users = tree
        .edges
        .keys()
        .filter(|(a, b)| {
            a.first().is_some_and(|x| x != "vocabulary")
                && b.first().is_some_and(|y| y == "vocabulary")
        })
        .count();
    assert!(
        users > 0,
        "the import reader sees no use of crate::vocabulary"
    );
}

/// The README's code block under "How the code is laid out": the lines naming a module as
/// `  name/` or `  name.rs` at the start of the line.
fn readme_layout() -> BTreeSet<String> {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let section = readme
        .split("## How the code is laid out")
        .nth(1)
        .expect("README.md has a section `## How the code is laid out`");
    let block = section
        .split("```")
        .nth(1)
        .expect("the layout section holds a code block");
    block
        .lines()
        .filter_map(|l| {
            let l = l.strip_prefix("  ")?;
            let word = l.split_whitespace().next()?;
            let name = word
                .strip_suffix('/')
                .or_else(|| word.strip_suffix(".rs"))?;
            Some(name.to_string())
        })
        .collect()
}

/// Docs that cannot drift: every top-level module under src/ (a file or a folder) is named
/// in the README's layout block, and the block names nothing that is not there.
#[test]
fn the_readme_layout_names_every_module() {
    let mut modules = top_level_modules();
    modules.extend(workspace_crates());
    modules.extend(["main", "lib", "bin"].map(String::from));
    let layout = readme_layout();
    let missing: Vec<_> = modules.difference(&layout).collect();
    let stale: Vec<_> = layout.difference(&modules).collect();
    assert!(
        missing.is_empty() && stale.is_empty(),
        "README.md's layout block (section `How the code is laid out`) is out of date: \
         not named {missing:?}; named but not in a crate's src/ {stale:?}. Add or remove the lines."
    );
}

/// The workspace's crates (folders of `crates/`), as the layout block names them (`core/`).
fn workspace_crates() -> BTreeSet<String> {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("crates");
    std::fs::read_dir(crates)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("Cargo.toml").exists())
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect()
}

/// Every crate of `crates/` is a member of the workspace and each member's `src/` is one the
/// house rules read (a crate added without telling them would escape every rule).
#[test]
fn the_house_rules_read_every_workspace_crate() {
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml")).unwrap();
    for c in workspace_crates() {
        assert!(
            manifest.contains(&format!("\"crates/{c}\"")),
            "crates/{c} is not a member of the workspace (root Cargo.toml [workspace] members)"
        );
        let src = format!("crates/{c}/src");
        assert!(
            SOURCE_ROOTS.iter().any(|(d, _, _)| *d == src),
            "{src} is not in tests/fast/house.rs SOURCE_ROOTS: the house rules would not read it"
        );
    }
}

/// Docs that cannot drift: every subcommand `rigmon --help` lists is in the README's tour
/// (a `rigmon NAME` in its table).
#[test]
fn the_readme_tour_names_every_subcommand() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .arg("--help")
        .output()
        .expect("rigmon --help runs");
    let help = String::from_utf8_lossy(&out.stdout);
    let commands: Vec<String> = help
        .split("Commands:")
        .nth(1)
        .expect("rigmon --help lists `Commands:`")
        .lines()
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|c| c != "help")
        .collect();
    assert!(
        commands.len() > 10,
        "too few subcommands parsed: {commands:?}"
    );
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let tour = readme
        .split("## A quick tour")
        .nth(1)
        .expect("README.md has a section `## A quick tour`")
        .split("\n## ")
        .next()
        .unwrap();
    let missing: Vec<_> = commands
        .iter()
        .filter(|c| !tour.contains(&format!("`rigmon {c}")))
        .collect();
    assert!(
        missing.is_empty(),
        "README.md's quick tour names no `rigmon NAME ...` row for {missing:?}: add one per subcommand"
    );
}
