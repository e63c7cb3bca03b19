//! No two source files of the workspace import each other, directly or through others.
//!
//! A file imports another when it names something the other defines: by a `use`
//! declaration (a re-export too), or by a path in its code (`crate::…`, `super::…`,
//! `self::…`, a child module's name, or a module it imported). A name is traced through
//! re-exports to the file that defines it, so a façade that re-exports its children makes
//! no cycle with them; a parent whose child names the parent's own items, while the parent
//! calls the child, does. Test modules (`#[cfg(test)]`) are left out: they may reach
//! anywhere.
//!
//! The check reads source text, as rustc's name resolution would see it closely enough for
//! this project's style: a name that cannot be traced is attributed to the module it was
//! looked up in.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

/// A module's path from its crate's root (`[]` is the root).
type ModPath = Vec<String>;

/// The workspace's crates whose files are checked: each source folder with its root file.
const CRATES: &[(&str, &str)] = &[
    ("shared/src", "lib.rs"),
    ("host/io/src", "lib.rs"),
    ("host/fullres/src", "lib.rs"),
    ("host/depth/src", "lib.rs"),
    ("host/sim/src", "lib.rs"),
    ("host/detect/src", "lib.rs"),
    ("host/link/src", "lib.rs"),
    ("host/src", "lib.rs"),
    // The `rollfuse` binary: its `commands` modules.
    ("host/src", "main.rs"),
    ("host/records/src", "lib.rs"),
    ("firmware/src", "lib.rs"),
    // The board's binary: its `mcu` modules.
    ("firmware/src", "main.rs"),
    ("python/src", "lib.rs"),
    ("tests/firmware-qemu/src", "main.rs"),
    ("tests/mcu-bench/src", "main.rs"),
];

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    Path,
    Punct(char),
}

/// `src` without comments, string and character literals (each left as a space).
fn strip_literals(src: &str) -> String {
    let b: Vec<char> = src.chars().collect();
    let mut out = String::with_capacity(src.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == '/' && b.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == '*' && b.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            out.push(' ');
        } else if c == 'r' && (next == Some('"') || next == Some('#')) && !ident_char_before(&b, i)
        {
            // A raw string: r"…", r#"…"#.
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            j += 1;
            while j < b.len() {
                if b[j] == '"' && (0..hashes).all(|h| b.get(j + 1 + h) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            i = j;
            out.push(' ');
        } else if c == '"' {
            i += 1;
            while i < b.len() && b[i] != '"' {
                i += if b[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            out.push(' ');
        } else if c == '\'' && is_char_literal(&b, i) {
            i += 1;
            while i < b.len() && b[i] != '\'' {
                i += if b[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            out.push(' ');
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

fn ident_char_before(b: &[char], i: usize) -> bool {
    i > 0 && (b[i - 1].is_alphanumeric() || b[i - 1] == '_')
}

/// Whether the quote at `i` opens a character literal, not a lifetime or a label.
fn is_char_literal(b: &[char], i: usize) -> bool {
    matches!(
        (b.get(i + 1), b.get(i + 2)),
        (Some('\\'), _) | (Some(_), Some('\''))
    )
}

fn tokens(text: &str) -> Vec<Tok> {
    let b: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
                i += 1;
            }
            out.push(Tok::Ident(b[start..i].iter().collect()));
        } else if c.is_ascii_digit() {
            while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_' || b[i] == '.') {
                i += 1;
            }
        } else if c == ':' && b.get(i + 1) == Some(&':') {
            out.push(Tok::Path);
            i += 2;
        } else {
            if !c.is_whitespace() {
                out.push(Tok::Punct(c));
            }
            i += 1;
        }
    }
    out
}

/// The tokens without the items under `#[cfg(test)]`, and the names of the test modules
/// declared as files.
fn without_tests(toks: Vec<Tok>) -> (Vec<Tok>, Vec<String>) {
    let ident = |t: Option<&Tok>, s: &str| matches!(t, Some(Tok::Ident(x)) if x == s);
    let mut out = Vec::with_capacity(toks.len());
    let mut test_files = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        let cfg_test = toks[i] == Tok::Punct('#')
            && toks.get(i + 1) == Some(&Tok::Punct('['))
            && ident(toks.get(i + 2), "cfg")
            && toks.get(i + 3) == Some(&Tok::Punct('('))
            && ident(toks.get(i + 4), "test")
            && toks.get(i + 5) == Some(&Tok::Punct(')'));
        if !cfg_test {
            out.push(toks[i].clone());
            i += 1;
            continue;
        }
        // Skip the attribute, then the item: up to its `;` or its balanced braces.
        i += 7;
        let mut depth = 0;
        while i < toks.len() {
            match &toks[i] {
                Tok::Ident(m) if m == "mod" && depth == 0 => {
                    if let (Some(Tok::Ident(name)), Some(Tok::Punct(';'))) =
                        (toks.get(i + 1), toks.get(i + 2))
                    {
                        test_files.push(name.clone());
                    }
                }
                Tok::Punct('{') => depth += 1,
                Tok::Punct('}') => {
                    depth -= 1;
                    if depth == 0 {
                        i += 1;
                        break;
                    }
                }
                Tok::Punct(';') if depth == 0 => {
                    i += 1;
                    break;
                }
                _ => {}
            }
            i += 1;
        }
    }
    (out, test_files)
}

/// A `use` declaration's leaves: each full path, and the name it binds (`None` for a glob).
fn use_tree(
    toks: &[Tok],
    i: &mut usize,
    prefix: &[String],
    out: &mut Vec<(Vec<String>, Option<String>)>,
) {
    let mut path = prefix.to_vec();
    loop {
        match toks.get(*i) {
            Some(Tok::Ident(s))
                if s == "self" && !path.is_empty() && path.len() == prefix.len() =>
            {
                *i += 1;
                let name = alias(toks, i).or(path.last().cloned());
                out.push((path.clone(), name));
                return;
            }
            Some(Tok::Ident(s)) => {
                path.push(s.clone());
                *i += 1;
                if toks.get(*i) == Some(&Tok::Path) {
                    *i += 1;
                    continue;
                }
                let name = alias(toks, i).or(path.last().cloned());
                out.push((path, name));
                return;
            }
            Some(Tok::Punct('*')) => {
                *i += 1;
                out.push((path, None));
                return;
            }
            Some(Tok::Punct('{')) => {
                *i += 1;
                while !matches!(toks.get(*i), Some(Tok::Punct('}')) | None) {
                    use_tree(toks, i, &path, out);
                    if toks.get(*i) == Some(&Tok::Punct(',')) {
                        *i += 1;
                    }
                }
                *i += 1;
                return;
            }
            _ => return,
        }
    }
}

fn alias(toks: &[Tok], i: &mut usize) -> Option<String> {
    if matches!(toks.get(*i), Some(Tok::Ident(a)) if a == "as")
        && let Some(Tok::Ident(name)) = toks.get(*i + 1)
    {
        *i += 2;
        return Some(name.clone());
    }
    None
}

/// What one file says: its names, its imports, the paths in its code.
#[derive(Debug, Default)]
struct File {
    path: PathBuf,
    defines: BTreeSet<String>,
    /// `use` leaves: the path as written and the name bound (`None`: a glob).
    uses: Vec<(Vec<String>, Option<String>)>,
    /// Paths of two or more segments in the code.
    paths: Vec<Vec<String>>,
    /// Child modules declared as files.
    children: BTreeSet<String>,
    /// Macros exported to the crate's root (`#[macro_export]`).
    exported_macros: BTreeSet<String>,
}

const DEFINING: &[&str] = &[
    "struct", "enum", "fn", "const", "static", "trait", "type", "union", "mod",
];

fn read_file(path: &Path) -> (File, Vec<String>) {
    let text = std::fs::read_to_string(path).unwrap();
    let (toks, test_files) = without_tests(tokens(&strip_literals(&text)));
    let mut file = File {
        path: path.to_path_buf(),
        ..File::default()
    };
    let mut i = 0;
    while i < toks.len() {
        match &toks[i] {
            Tok::Ident(k) if k == "use" => {
                i += 1;
                use_tree(&toks, &mut i, &[], &mut file.uses);
            }
            Tok::Ident(k) if DEFINING.contains(&k.as_str()) || k == "macro_rules" => {
                let at = if k == "macro_rules" { i + 2 } else { i + 1 };
                if let Some(Tok::Ident(name)) = toks.get(at) {
                    file.defines.insert(name.clone());
                    let exported = i >= 2 && toks[i - 2] == Tok::Ident("macro_export".into());
                    if k == "macro_rules" && exported {
                        file.exported_macros.insert(name.clone());
                    }
                    if k == "mod" && toks.get(at + 1) == Some(&Tok::Punct(';')) {
                        file.children.insert(name.clone());
                    }
                }
                i += 1;
            }
            Tok::Ident(first) if i == 0 || toks[i - 1] != Tok::Path => {
                let mut path = vec![first.clone()];
                let mut j = i + 1;
                while toks.get(j) == Some(&Tok::Path) {
                    match toks.get(j + 1) {
                        Some(Tok::Ident(s)) => path.push(s.clone()),
                        _ => break,
                    }
                    j += 2;
                }
                if path.len() > 1 {
                    file.paths.push(path);
                }
                i = j.max(i + 1);
            }
            _ => i += 1,
        }
    }
    for t in &test_files {
        file.children.remove(t);
    }
    (file, test_files)
}

/// One crate's files by module path.
struct Crate {
    files: BTreeMap<ModPath, File>,
}

impl Crate {
    fn read(src: &Path, root: &str) -> Self {
        let mut files = BTreeMap::new();
        let mut queue = vec![(Vec::<String>::new(), src.join(root), src.to_path_buf())];
        while let Some((module, path, dir)) = queue.pop() {
            let (file, _) = read_file(&path);
            for child in &file.children {
                let flat = dir.join(format!("{child}.rs"));
                let (child_path, child_dir) = if flat.exists() {
                    (flat, dir.join(child))
                } else {
                    (dir.join(child).join("mod.rs"), dir.join(child))
                };
                let mut m = module.clone();
                m.push(child.clone());
                queue.push((m, child_path, child_dir));
            }
            files.insert(module, file);
        }
        Self { files }
    }

    /// `written`, as named from `module`, from the crate's root; `None` for another crate's
    /// or a local name.
    fn absolute(&self, module: &ModPath, written: &[String]) -> Option<Vec<String>> {
        let (first, rest) = written.split_first()?;
        let mut base = match first.as_str() {
            "crate" => Vec::new(),
            "self" => module.clone(),
            "super" => {
                let mut up = module.clone();
                up.pop();
                let mut rest = rest;
                while rest.first().is_some_and(|s| s == "super") {
                    up.pop();
                    rest = &rest[1..];
                }
                up.extend(rest.iter().cloned());
                return Some(up);
            }
            _ if self.files[module].children.contains(first) => {
                let mut m = module.clone();
                m.push(first.clone());
                m
            }
            _ => {
                // A name this file imported: the path it stands for.
                let file = &self.files[module];
                // (`use image::{self, …}` binds another crate's name to itself.)
                let (target, _) = file.uses.iter().find(|(target, name)| {
                    name.as_ref() == Some(first) && target.first() != Some(first)
                })?;
                let mut t = self.absolute(module, target)?;
                t.extend(rest.iter().cloned());
                return Some(t);
            }
        };
        base.extend(rest.iter().cloned());
        Some(base)
    }

    /// The module whose file defines what `path` (from the root) names.
    fn defining(&self, path: &[String], depth: usize) -> Option<ModPath> {
        let mut module: ModPath = Vec::new();
        let mut rest = path;
        while let Some((seg, tail)) = rest.split_first() {
            let mut deeper = module.clone();
            deeper.push(seg.clone());
            if !self.files.contains_key(&deeper) {
                break;
            }
            module = deeper;
            rest = tail;
        }
        let Some(name) = rest.first() else {
            return Some(module);
        };
        let file = &self.files[&module];
        if file.defines.contains(name) || depth > 8 {
            return Some(module);
        }
        if module.is_empty()
            && let Some((m, _)) = self
                .files
                .iter()
                .find(|(_, f)| f.exported_macros.contains(name))
        {
            return Some(m.clone());
        }
        for (target, bound) in &file.uses {
            if bound.as_ref() == Some(name) {
                let mut t = self.absolute(&module, target)?;
                t.extend(rest[1..].iter().cloned());
                return self.defining(&t, depth + 1);
            }
        }
        for (target, _) in file.uses.iter().filter(|(_, bound)| bound.is_none()) {
            if let Some(mut t) = self.absolute(&module, target) {
                t.extend(rest.iter().cloned());
                if let Some(m) = self.defining(&t, depth + 1)
                    && self.files[&m].defines.contains(name)
                {
                    return Some(m);
                }
            }
        }
        Some(module)
    }

    /// Which files each file imports, with the names it takes.
    fn imports(&self) -> BTreeMap<ModPath, BTreeMap<ModPath, BTreeSet<String>>> {
        let mut out: BTreeMap<_, BTreeMap<_, BTreeSet<_>>> = BTreeMap::new();
        for (module, file) in &self.files {
            let written = file.uses.iter().map(|(p, _)| p).chain(&file.paths);
            for path in written {
                let Some(abs) = self.absolute(module, path) else {
                    continue;
                };
                let Some(target) = self.defining(&abs, 0) else {
                    continue;
                };
                if &target != module {
                    let name = path.last().cloned().unwrap_or_default();
                    out.entry(module.clone())
                        .or_default()
                        .entry(target)
                        .or_default()
                        .insert(name);
                }
            }
        }
        out
    }
}

/// The strongly connected components of more than one module (Tarjan's algorithm).
fn cycles(edges: &BTreeMap<ModPath, BTreeMap<ModPath, BTreeSet<String>>>) -> Vec<Vec<ModPath>> {
    struct State<'a> {
        edges: &'a BTreeMap<ModPath, BTreeMap<ModPath, BTreeSet<String>>>,
        index: HashMap<ModPath, usize>,
        low: HashMap<ModPath, usize>,
        stack: Vec<ModPath>,
        found: Vec<Vec<ModPath>>,
    }
    fn visit(s: &mut State, v: &ModPath) {
        let n = s.index.len();
        s.index.insert(v.clone(), n);
        s.low.insert(v.clone(), n);
        s.stack.push(v.clone());
        let next: Vec<ModPath> = s
            .edges
            .get(v)
            .map(|e| e.keys().cloned().collect())
            .unwrap_or_default();
        for w in &next {
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                s.low.entry(v.clone()).and_modify(|l| *l = (*l).min(lw));
            } else if s.stack.contains(w) {
                let iw = s.index[w];
                s.low.entry(v.clone()).and_modify(|l| *l = (*l).min(iw));
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = s.stack.pop() {
                let done = &w == v;
                comp.push(w);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.found.push(comp);
            }
        }
    }
    let mut s = State {
        edges,
        index: HashMap::new(),
        low: HashMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    for v in edges.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.found
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

#[test]
fn no_two_source_files_import_each_other() {
    let mut report = String::new();
    for (src, root) in CRATES {
        let krate = Crate::read(&workspace().join(src), root);
        let edges = krate.imports();
        for cycle in cycles(&edges) {
            report.push_str(&format!("a cycle of {} files in {src}:\n", cycle.len()));
            for a in &cycle {
                for (b, names) in &edges[a] {
                    if cycle.contains(b) {
                        let names: Vec<_> = names.iter().map(String::as_str).collect();
                        report.push_str(&format!(
                            "  {} -> {}: {}\n",
                            krate.files[a].path.display(),
                            krate.files[b].path.display(),
                            names.join(", ")
                        ));
                    }
                }
            }
        }
    }
    assert!(report.is_empty(), "{report}");
}

/// The check itself, on a crate written to show each kind of import.
#[test]
fn the_check_sees_uses_paths_and_re_exports() {
    let dir = tempfile_dir();
    let write = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    };
    write("lib.rs", "mod a;\nmod b;\nmod c;\npub use c::Shared;\n");
    write(
        "a.rs",
        "use crate::b::Bee;\n/// crate::c::never in a comment\npub struct Ay;\n",
    );
    write(
        "b.rs",
        "pub struct Bee;\nfn f() { let s = \"crate::a::Ay\"; crate::Shared::new(); }\n",
    );
    write(
        "c.rs",
        "pub struct Shared;\n#[cfg(test)]\nmod tests { use crate::a::Ay; }\n",
    );
    let krate = Crate::read(&dir, "lib.rs");
    let edges = krate.imports();
    let m = |s: &str| vec![s.to_string()];
    let targets = |s: &str| -> Vec<ModPath> {
        edges
            .get(&m(s))
            .map(|e| e.keys().cloned().collect())
            .unwrap_or_default()
    };
    assert_eq!(targets("a"), vec![m("b")]);
    // Through the root's re-export to the file that defines it; strings are not paths.
    assert_eq!(targets("b"), vec![m("c")]);
    // Test modules reach anywhere.
    assert!(targets("c").is_empty());
    assert!(cycles(&edges).is_empty());
    write(
        "c.rs",
        "pub struct Shared;\nfn g() -> crate::b::Bee { todo!() }\n",
    );
    write("b.rs", "pub struct Bee;\nuse crate::Shared;\n");
    let edges = Crate::read(&dir, "lib.rs").imports();
    assert_eq!(cycles(&edges), vec![vec![m("b"), m("c")]]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A fresh folder for one test.
fn tempfile_dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rollfuse-import-cycles-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
