//! The house rules of `src/`, checked from the source text (std only, no
//! compiler): which file imports which, which room (top-level module) may
//! import which, and what the pure floors never touch. `docs/architecture.md`
//! explains the rules; its table of rooms is the one the checks read.
//!
//! How an import is found: every `src/**/*.rs` is read without its comments
//! and without its `#[cfg(test)]` items (unit-test files — `tests.rs`,
//! `*_tests.rs` — are skipped whole; test helpers such as `testing.rs` are
//! checked like any file). `use` trees (nested groups, `self`, renames, `*`),
//! `crate::`/`super::`/`self::` paths in code, and paths through a child
//! module or an imported module are resolved to the deepest existing file of
//! the path: `crate::a::b::C` is `src/a/b.rs` or `src/a/b/mod.rs`, else
//! `src/a.rs`/`src/a/mod.rs`. A re-export is a use like any other. Declaring
//! a child (`mod x;`) is not an import of it; naming something in it is. A
//! file naming something of a module that encloses it (a child reading its
//! parent's `super::Name`) draws no arrow: the child lives inside its parent,
//! which owns it; the parent's imports from its children do count.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The floors up to which code is pure and deterministic.
const PURE_UP_TO_FLOOR: u32 = 7;
/// Names a pure room never uses (as path segments or identifiers).
const IMPURE: &[(&str, &str)] = &[
    ("tokio", "the async runtime"),
    ("mavlink::", "the protocol"),
    ("std::time", "the clock"),
    ("SystemTime", "the clock"),
    ("Instant::now", "the clock"),
    ("thread_rng", "the global RNG"),
];
/// The flight stack's rooms: they see sensor readings, never the world.
const FLIGHT_STACK: &[&str] = &["autopilot", "control", "estimation"];
/// Rooms the flight stack never names.
const NOT_FOR_THE_FLIGHT_STACK: &[&str] = &["sim", "lockstep", "scenario", "link", "daemon", "logs"];
/// Imports that are wrong whatever the table says: (from room, to room, why).
const NEVER: &[(&str, &str, &str)] = &[
    (
        "airframe",
        "control",
        "the [control] table is checked by control, which imports airframe",
    ),
    (
        "link",
        "sim",
        "protocol code never touches physics: it sees the world only in a lockstep::Snapshot",
    ),
];

// ---------------------------------------------------------------- lexing

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    Str(String),
    /// `::`
    Sep,
    Punct(char),
}

#[derive(Clone, Debug)]
struct Token {
    tok: Tok,
    line: usize,
}

impl Token {
    fn is_ident(&self, s: &str) -> bool {
        matches!(&self.tok, Tok::Ident(i) if i == s)
    }
    fn ident(&self) -> Option<&str> {
        match &self.tok {
            Tok::Ident(i) => Some(i),
            _ => None,
        }
    }
    fn is_punct(&self, c: char) -> bool {
        self.tok == Tok::Punct(c)
    }
    fn is_sep(&self) -> bool {
        self.tok == Tok::Sep
    }
}

/// Rust source to tokens: comments dropped, string literals kept as one
/// token, lifetimes and numbers dropped.
fn lex(src: &str) -> Vec<Token> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    let ident_start = |ch: char| ch.is_alphabetic() || ch == '_';
    let ident_char = |ch: char| ch.is_alphanumeric() || ch == '_';
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied().unwrap_or('\0');
        if ch == '\n' {
            line += 1;
            i += 1;
        } else if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && next == '/' {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && next == '*' {
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
                    if c[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if (ch == 'r' || (ch == 'b' && next == 'r')) && raw_string_at(&c, i).is_some() {
            let (start, hashes) = raw_string_at(&c, i).unwrap();
            let (first_line, mut j, mut s) = (line, start, String::new());
            loop {
                if j >= c.len() {
                    break;
                }
                if c[j] == '"' && (0..hashes).all(|h| c.get(j + 1 + h) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                if c[j] == '\n' {
                    line += 1;
                }
                s.push(c[j]);
                j += 1;
            }
            out.push(Token {
                tok: Tok::Str(s),
                line: first_line,
            });
            i = j;
        } else if ch == '"' || (ch == 'b' && next == '"') {
            let first_line = line;
            let mut j = if ch == 'b' { i + 2 } else { i + 1 };
            let mut s = String::new();
            while j < c.len() && c[j] != '"' {
                if c[j] == '\\' {
                    s.push(c[j]);
                    j += 1;
                }
                if j < c.len() {
                    if c[j] == '\n' {
                        line += 1;
                    }
                    s.push(c[j]);
                }
                j += 1;
            }
            out.push(Token {
                tok: Tok::Str(s),
                line: first_line,
            });
            i = j + 1;
        } else if ch == '\'' || (ch == 'b' && next == '\'') {
            // a char literal ('x', '\n', '\u{..}') or a lifetime ('a)
            let j = if ch == 'b' { i + 1 } else { i };
            if c.get(j + 1) == Some(&'\\') {
                let mut k = j + 3; // past the escaped character
                while k < c.len() && c[k] != '\'' {
                    k += 1;
                }
                i = k + 1;
            } else if c.get(j + 2) == Some(&'\'') {
                i = j + 3;
            } else {
                i = j + 1;
                while i < c.len() && ident_char(c[i]) {
                    i += 1;
                }
            }
        } else if ch.is_ascii_digit() {
            while i < c.len() && (ident_char(c[i]) || (c[i] == '.' && c.get(i + 1).is_some_and(|d| d.is_ascii_digit())))
            {
                i += 1;
            }
        } else if ch == '$' && c[i + 1..].starts_with(&['c', 'r', 'a', 't', 'e']) {
            out.push(Token {
                tok: Tok::Ident("crate".into()),
                line,
            });
            i += 6;
        } else if ident_start(ch) {
            if ch == 'r' && next == '#' && c.get(i + 2).is_some_and(|&d| ident_start(d)) {
                i += 2; // a raw identifier
            }
            let start = i;
            while i < c.len() && ident_char(c[i]) {
                i += 1;
            }
            out.push(Token {
                tok: Tok::Ident(c[start..i].iter().collect()),
                line,
            });
        } else if ch == ':' && next == ':' {
            out.push(Token { tok: Tok::Sep, line });
            i += 2;
        } else {
            out.push(Token {
                tok: Tok::Punct(ch),
                line,
            });
            i += 1;
        }
    }
    out
}

/// At a raw string (`r"`, `r#"`, `br#"`): where its text starts and how many
/// `#` close it.
fn raw_string_at(c: &[char], i: usize) -> Option<(usize, usize)> {
    let mut j = if c[i] == 'b' { i + 2 } else { i + 1 };
    if i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_') {
        return None;
    }
    let mut hashes = 0;
    while c.get(j) == Some(&'#') {
        hashes += 1;
        j += 1;
    }
    (c.get(j) == Some(&'"')).then_some((j + 1, hashes))
}

/// The index just past the bracketed group opening at `i` (`(`, `[`, `{`).
fn skip_group(t: &[Token], i: usize) -> usize {
    let mut depth = 0i32;
    let mut j = i;
    while j < t.len() {
        match t[j].tok {
            Tok::Punct('(' | '[' | '{') => depth += 1,
            Tok::Punct(')' | ']' | '}') => {
                depth -= 1;
                if depth == 0 {
                    return j + 1;
                }
            }
            _ => {}
        }
        j += 1;
    }
    j
}

/// The tokens without the items under `#[cfg(test)]`.
fn drop_test_items(t: Vec<Token>) -> Vec<Token> {
    let is_cfg_test = |i: usize| {
        let want = ["#", "[", "cfg", "(", "test", ")", "]"];
        want.iter().enumerate().all(|(k, w)| {
            t.get(i + k).is_some_and(|tok| match &tok.tok {
                Tok::Ident(s) => s == w,
                Tok::Punct(p) => w.len() == 1 && w.starts_with(*p),
                _ => false,
            })
        })
    };
    let mut out = Vec::with_capacity(t.len());
    let mut i = 0;
    while i < t.len() {
        if !is_cfg_test(i) {
            out.push(t[i].clone());
            i += 1;
            continue;
        }
        i += 7;
        // further attributes, then the item: up to `;` or `,` at depth 0, or
        // through its `{ .. }` block, or up to the close of what holds it
        while i < t.len() && t[i].is_punct('#') {
            i = skip_group(&t, i + 1);
        }
        while i < t.len() {
            match t[i].tok {
                Tok::Punct(';' | ',') => {
                    i += 1;
                    break;
                }
                Tok::Punct('{') => {
                    i = skip_group(&t, i);
                    break;
                }
                Tok::Punct('(' | '[') => i = skip_group(&t, i),
                Tok::Punct(')' | ']' | '}') => break,
                _ => i += 1,
            }
        }
    }
    out
}

// ---------------------------------------------------------------- the crate

/// A module path below the crate root (`["autopilot", "navigator"]`).
type ModPath = Vec<String>;

struct SrcFile {
    /// `src/autopilot/failsafe.rs`
    name: String,
    room: String,
    /// The file's own module (empty for `lib.rs`).
    module: ModPath,
    tokens: Vec<Token>,
}

fn is_unit_test_file(rel: &str) -> bool {
    let file = rel.rsplit('/').next().unwrap_or(rel);
    file == "tests.rs" || file.ends_with("_tests.rs")
}

fn rs_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap_or_else(|e| panic!("reading {}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rs_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read_crate() -> Vec<SrcFile> {
    let mut paths = Vec::new();
    rs_files(&root().join("src"), &mut paths);
    paths.sort();
    let mut files = Vec::new();
    for path in paths {
        let rel = path.strip_prefix(root()).unwrap().to_string_lossy().replace('\\', "/");
        if is_unit_test_file(&rel) {
            continue;
        }
        let inner = rel.strip_prefix("src/").unwrap().strip_suffix(".rs").unwrap();
        let mut module: ModPath = inner.split('/').map(String::from).collect();
        if module.last().is_some_and(|m| m == "mod") {
            module.pop();
        }
        if inner == "lib" || inner == "main" {
            module.clear();
        }
        let room = match inner {
            "lib" | "main" => inner.to_string(),
            _ => module[0].clone(),
        };
        let text = fs::read_to_string(&path).unwrap();
        files.push(SrcFile {
            name: rel,
            room,
            module,
            tokens: drop_test_items(lex(&text)),
        });
    }
    files
}

/// A `use` tree flattened: the path as written, and the name it brings in
/// (`None` for a glob).
fn use_leaves(t: &[Token], mut i: usize, prefix: &[String], out: &mut Vec<(Vec<String>, Option<String>)>) -> usize {
    let mut path = prefix.to_vec();
    while i < t.len() {
        match &t[i].tok {
            Tok::Ident(s) if s == "as" => {
                let alias = t[i + 1].ident().unwrap_or("_").to_string();
                out.push((path.clone(), Some(alias)));
                return i + 2;
            }
            Tok::Ident(s) => {
                path.push(s.clone());
                i += 1;
            }
            Tok::Sep => i += 1,
            Tok::Punct('*') => {
                out.push((path.clone(), None));
                return i + 1;
            }
            Tok::Punct('{') => {
                i += 1;
                while i < t.len() && !t[i].is_punct('}') {
                    i = use_leaves(t, i, &path, out);
                    if t[i].is_punct(',') {
                        i += 1;
                    }
                }
                return i + 1;
            }
            _ => break,
        }
    }
    if path.last().is_some_and(|s| s == "self") {
        path.pop();
    }
    if path.len() > prefix.len() || !path.is_empty() {
        let name = path.last().cloned();
        out.push((path, name));
    }
    i
}

/// One `use` leaf of a file.
struct UseLeaf {
    module: ModPath,
    written: Vec<String>,
    name: Option<String>,
    line: usize,
    resolved: Option<Vec<String>>,
}

/// What a file refers to: its `use` leaves and its code paths
/// (`a::b::c` starting at `crate`, `super`, `self`, a child module or an
/// imported name), each with the module it sits in.
struct Refs {
    uses: Vec<UseLeaf>,
    paths: Vec<(ModPath, Vec<String>, usize)>,
}

/// Walks a file: the inline modules it opens (`mod x { .. }`), the children
/// it declares (`mod x;`), and its references.
fn walk(f: &SrcFile, inline: &mut BTreeMap<ModPath, String>) -> Refs {
    let t = &f.tokens;
    let mut refs = Refs {
        uses: Vec::new(),
        paths: Vec::new(),
    };
    let mut stack: Vec<(ModPath, i32)> = vec![(f.module.clone(), 0)];
    let mut depth = 0i32;
    let mut i = 0;
    while i < t.len() {
        let module = stack.last().unwrap().0.clone();
        match &t[i].tok {
            Tok::Punct('{') => depth += 1,
            Tok::Punct('}') => {
                depth -= 1;
                if stack.len() > 1 && stack.last().unwrap().1 == depth {
                    stack.pop();
                }
            }
            Tok::Ident(s) if s == "mod" && t.get(i + 1).and_then(Token::ident).is_some() => {
                if t.get(i + 2).is_some_and(|n| n.is_punct('{')) {
                    let mut m = module.clone();
                    m.push(t[i + 1].ident().unwrap().to_string());
                    inline.insert(m.clone(), f.name.clone());
                    stack.push((m, depth));
                }
                i += 2;
                continue;
            }
            Tok::Ident(s) if s == "pub" && t.get(i + 1).is_some_and(|n| n.is_punct('(')) => {
                i = skip_group(t, i + 1); // pub(crate), pub(in crate::x)
                continue;
            }
            Tok::Ident(s) if s == "use" => {
                let mut leaves = Vec::new();
                let end = use_leaves(t, i + 1, &[], &mut leaves);
                for (written, name) in leaves {
                    refs.uses.push(UseLeaf {
                        module: module.clone(),
                        written,
                        name,
                        line: t[i].line,
                        resolved: None,
                    });
                }
                i = end;
                continue;
            }
            Tok::Ident(s) => {
                let starts_path = t.get(i + 1).is_some_and(Token::is_sep)
                    && t.get(i + 2).and_then(Token::ident).is_some()
                    && !(i > 0 && (t[i - 1].is_sep() || t[i - 1].is_punct('.')));
                if starts_path {
                    let mut segs = vec![s.clone()];
                    let line = t[i].line;
                    let mut j = i + 1;
                    while t.get(j).is_some_and(Token::is_sep) {
                        match t.get(j + 1).and_then(Token::ident) {
                            Some(n) => segs.push(n.to_string()),
                            None => break,
                        }
                        j += 2;
                    }
                    refs.paths.push((module, segs, line));
                    i = j;
                    continue;
                }
            }
            _ => {}
        }
        i += 1;
    }
    refs
}

/// Where a name or path of the crate lives.
#[derive(Clone, Debug)]
struct Target {
    file: String,
    name: String,
}

struct Crate {
    files: Vec<SrcFile>,
    /// every module (file or inline) and its file
    modules: BTreeMap<ModPath, String>,
    /// per file: the names its `use`s bring in -> absolute paths
    aliases: Vec<BTreeMap<String, Vec<String>>>,
    refs: Vec<Refs>,
}

impl Crate {
    fn read() -> Crate {
        let files = read_crate();
        let mut modules = BTreeMap::new();
        for f in &files {
            if f.name != "src/main.rs" {
                modules.insert(f.module.clone(), f.name.clone());
            }
        }
        let mut inline = BTreeMap::new();
        let refs: Vec<Refs> = files.iter().map(|f| walk(f, &mut inline)).collect();
        modules.extend(inline);
        let mut c = Crate {
            aliases: vec![BTreeMap::new(); files.len()],
            files,
            modules,
            refs,
        };
        // `use`s may build on each other (`use crate::sim; use sim::Truth;`)
        for _ in 0..4 {
            for fi in 0..c.files.len() {
                for ui in 0..c.refs[fi].uses.len() {
                    if c.refs[fi].uses[ui].resolved.is_some() {
                        continue;
                    }
                    let u = &c.refs[fi].uses[ui];
                    let Some(abs) = c.absolute(fi, &u.module, &u.written) else {
                        continue;
                    };
                    if let Some(name) = u.name.clone() {
                        c.aliases[fi].insert(name, abs.clone());
                    }
                    c.refs[fi].uses[ui].resolved = Some(abs);
                }
            }
        }
        c
    }

    /// A path as written in module `module` of file `fi`, made absolute;
    /// `None` when it leads out of the crate (std, a dependency, a local item).
    fn absolute(&self, fi: usize, module: &ModPath, written: &[String]) -> Option<Vec<String>> {
        let first = written.first()?;
        let mut at = module.clone();
        let mut rest = written;
        if self.files[fi].name == "src/main.rs" {
            return (first == "rotorpilot").then(|| written[1..].to_vec());
        }
        match first.as_str() {
            "crate" => return Some(written[1..].to_vec()),
            "self" | "super" => {
                while let Some(s) = rest.first() {
                    match s.as_str() {
                        "self" => {}
                        "super" => {
                            at.pop()?;
                        }
                        _ => break,
                    }
                    rest = &rest[1..];
                }
            }
            _ => {
                let mut child = module.clone();
                child.push(first.clone());
                if !self.modules.contains_key(&child) {
                    let alias = self.aliases[fi].get(first)?;
                    return Some(alias.iter().chain(&written[1..]).cloned().collect());
                }
            }
        }
        Some(at.into_iter().chain(rest.iter().cloned()).collect())
    }

    /// The file an absolute path leads to: its deepest existing module's.
    fn target(&self, abs: &[String]) -> Target {
        let k = (0..=abs.len())
            .rev()
            .find(|&k| self.modules.contains_key(&abs[..k]))
            .unwrap();
        let name = abs.get(k).or(abs.last()).cloned().unwrap_or_else(|| "crate".into());
        Target {
            file: self.modules[&abs[..k]].clone(),
            name,
        }
    }

    /// Whether `file`'s module encloses `f` (its parent, grandparent, ..).
    fn encloses(&self, file: &str, f: &SrcFile) -> bool {
        let outer = &self.files.iter().find(|g| g.name == file).unwrap().module;
        f.name != "src/main.rs" && outer.len() < f.module.len() && f.module.starts_with(outer)
    }

    fn room_of(&self, file: &str) -> String {
        self.files
            .iter()
            .find(|f| f.name == file)
            .map(|f| f.room.clone())
            .unwrap_or_default()
    }

    /// The file-level import graph: from -> to -> (names, first line).
    fn graph(&self) -> Graph {
        let mut g: Graph = BTreeMap::new();
        for (fi, f) in self.files.iter().enumerate() {
            let r = &self.refs[fi];
            let mut add = |t: Target, line: usize| {
                if t.file != f.name && !self.encloses(&t.file, f) {
                    let e = g.entry(f.name.clone()).or_default().entry(t.file).or_default();
                    e.0.insert(t.name);
                    e.1 = if e.1 == 0 { line } else { e.1.min(line) };
                }
            };
            for u in &r.uses {
                let Some(abs) = &u.resolved else { continue };
                match &u.name {
                    // a glob: everything of that module
                    None => {
                        let t = self.target(abs);
                        add(
                            Target {
                                file: t.file,
                                name: "*".into(),
                            },
                            u.line,
                        );
                    }
                    // a module brought into scope is followed where it is named
                    Some(_) => {
                        if !self.modules.contains_key(abs) {
                            add(self.target(abs), u.line);
                        }
                    }
                }
            }
            for (module, segs, line) in &r.paths {
                if let Some(abs) = self.absolute(fi, module, segs)
                    && !self.modules.contains_key(&abs)
                {
                    add(self.target(&abs), *line);
                }
            }
        }
        g
    }
}

/// from -> to -> (the names that tie them, the first line naming one)
type Graph = BTreeMap<String, BTreeMap<String, (BTreeSet<String>, usize)>>;

fn names(set: &BTreeSet<String>) -> String {
    set.iter().cloned().collect::<Vec<_>>().join(", ")
}

/// Strongly connected components with more than one node (Tarjan).
fn circles(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct St<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        on: BTreeSet<&'a str>,
        stack: Vec<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut St<'a>, v: &'a str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on.insert(v);
        if let Some(next) = s.g.get(v) {
            for w in next {
                let w = w.as_str();
                if !s.index.contains_key(w) {
                    visit(s, w);
                    let lw = s.low[w];
                    let lv = s.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if s.on.contains(w) {
                    let iw = s.index[w];
                    let lv = s.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on.remove(w);
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = St {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        on: BTreeSet::new(),
        stack: Vec::new(),
        out: Vec::new(),
    };
    for v in g.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out
}

/// One way round a circle, from its first node back to it (breadth first,
/// inside the circle).
fn way_round(comp: &[String], next: impl Fn(&str) -> Vec<String>) -> Vec<String> {
    let start = comp[0].clone();
    let mut came_from: BTreeMap<String, String> = BTreeMap::new();
    let mut queue = std::collections::VecDeque::from([start.clone()]);
    while let Some(v) = queue.pop_front() {
        for w in next(&v) {
            if !comp.contains(&w) {
                continue;
            }
            if w == start {
                let mut way = vec![start.clone(), v.clone()];
                let mut at = v;
                while at != start {
                    at = came_from[&at].clone();
                    way.push(at.clone());
                }
                way.reverse();
                return way;
            }
            if !came_from.contains_key(&w) {
                came_from.insert(w.clone(), v.clone());
                queue.push_back(w);
            }
        }
    }
    comp.to_vec()
}

/// Describes circles in a graph whose arrows carry names.
fn describe_circles(g: &BTreeMap<String, BTreeMap<String, BTreeSet<String>>>, what: &str) -> Vec<String> {
    let plain: BTreeMap<String, BTreeSet<String>> = g
        .iter()
        .map(|(k, v)| (k.clone(), v.keys().cloned().collect()))
        .collect();
    let mut found = Vec::new();
    for comp in circles(&plain) {
        let way = way_round(&comp, |v| {
            plain.get(v).map(|s| s.iter().cloned().collect()).unwrap_or_default()
        });
        let mut s = format!("a circle of {what}: {}", way[0]);
        for pair in way.windows(2) {
            s += &format!(" -> {} ({})", pair[1], names(&g[&pair[0]][&pair[1]]));
        }
        s += &format!("\n  all arrows inside it ({}):", comp.join(", "));
        for a in &comp {
            for (b, n) in g.get(a).into_iter().flatten() {
                if comp.contains(b) {
                    s += &format!("\n    {a} -> {b} ({})", names(n));
                }
            }
        }
        found.push(s);
    }
    found
}

// ---------------------------------------------------------------- the table

struct Room {
    floor: u32,
    may_import: BTreeSet<String>,
}

/// The table of rooms in docs/architecture.md: `| floor | room | job | may
/// import |`, rooms in backticks (other text in the last column is remark).
fn table() -> BTreeMap<String, Room> {
    let path = root().join("docs/architecture.md");
    let text = fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let cells = |l: &str| -> Vec<String> {
        l.trim()
            .trim_matches('|')
            .split('|')
            .map(|c| c.trim().to_string())
            .collect()
    };
    let ticked = |c: &str| -> Vec<String> { c.split('`').skip(1).step_by(2).map(String::from).collect() };
    let mut lines = text.lines().skip_while(|l| {
        let h: Vec<String> = cells(l).iter().map(|c| c.to_lowercase()).collect();
        h != ["floor", "room", "job", "may import"]
    });
    assert!(
        lines.next().is_some(),
        "docs/architecture.md has no table `| floor | room | job | may import |`"
    );
    let mut rooms = BTreeMap::new();
    for l in lines.skip(1).take_while(|l| l.trim_start().starts_with('|')) {
        let c = cells(l);
        assert_eq!(
            c.len(),
            4,
            "docs/architecture.md: a row of the rooms table needs 4 cells: {l}"
        );
        let floor = c[0]
            .parse()
            .unwrap_or_else(|_| panic!("docs/architecture.md: the floor is a number: {l}"));
        let name = ticked(&c[1]);
        assert_eq!(
            name.len(),
            1,
            "docs/architecture.md: one room per row, in backticks: {l}"
        );
        rooms.insert(
            name[0].clone(),
            Room {
                floor,
                may_import: ticked(&c[3]).into_iter().collect(),
            },
        );
    }
    assert!(!rooms.is_empty(), "docs/architecture.md: the rooms table has no rows");
    rooms
}

fn fail_on(findings: Vec<String>, what: &str) {
    if !findings.is_empty() {
        panic!("{} {what}:\n\n{}\n", findings.len(), findings.join("\n\n"));
    }
}

// ---------------------------------------------------------------- the checks

#[test]
fn no_file_imports_itself_in_a_circle() {
    let c = Crate::read();
    let g: BTreeMap<_, BTreeMap<_, _>> = c
        .graph()
        .into_iter()
        .map(|(a, to)| (a, to.into_iter().map(|(b, (n, _))| (b, n)).collect()))
        .collect();
    fail_on(
        describe_circles(&g, "files"),
        "circle(s) of files importing each other (break one arrow: move the shared name down into a leaf)",
    );
}

/// The room graph: room -> room -> "file -> file (names)" arrows.
fn room_graph(c: &Crate) -> BTreeMap<String, BTreeMap<String, BTreeSet<String>>> {
    let mut rg: BTreeMap<String, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (a, to) in c.graph() {
        for (b, (n, line)) in to {
            let (ra, rb) = (c.room_of(&a), c.room_of(&b));
            if ra != rb {
                rg.entry(ra)
                    .or_default()
                    .entry(rb)
                    .or_default()
                    .insert(format!("{a}:{line} -> {b}: {}", names(&n)));
            }
        }
    }
    rg
}

#[test]
fn no_room_imports_itself_in_a_circle() {
    let c = Crate::read();
    fail_on(
        describe_circles(&room_graph(&c), "rooms"),
        "circle(s) of rooms importing each other",
    );
}

#[test]
fn rooms_import_only_what_the_table_allows() {
    let c = Crate::read();
    let rooms = table();
    let mut findings = Vec::new();
    for (name, room) in &rooms {
        for m in &room.may_import {
            match rooms.get(m) {
                None => findings.push(format!(
                    "docs/architecture.md: `{name}` may import `{m}`, which has no row"
                )),
                Some(r) if r.floor > room.floor => findings.push(format!(
                    "docs/architecture.md: `{name}` (floor {}) may import `{m}` on floor {}, above it",
                    room.floor, r.floor
                )),
                Some(_) => {}
            }
        }
    }
    let in_code: BTreeSet<String> = c.files.iter().map(|f| f.room.clone()).filter(|r| r != "lib").collect();
    for r in &in_code {
        if !rooms.contains_key(r) {
            let files: Vec<_> = c
                .files
                .iter()
                .filter(|f| &f.room == r)
                .map(|f| f.name.as_str())
                .collect();
            findings.push(format!(
                "room `{r}` ({}) has no row in docs/architecture.md",
                files.join(", ")
            ));
        }
    }
    for r in rooms.keys() {
        if !in_code.contains(r) {
            findings.push(format!(
                "docs/architecture.md has a row for `{r}`, which is no module of src/"
            ));
        }
    }
    for (ra, to) in room_graph(&c) {
        for (rb, arrows) in to {
            let allowed = rooms.get(&ra).is_some_and(|r| r.may_import.contains(&rb));
            if !allowed && rooms.contains_key(&ra) && rooms.contains_key(&rb) {
                let arrows: Vec<_> = arrows.iter().map(|a| format!("\n    {a}")).collect();
                findings.push(format!(
                    "`{ra}` imports `{rb}`, which docs/architecture.md does not allow:{}",
                    arrows.concat()
                ));
            }
        }
    }
    fail_on(findings, "import(s) between rooms against docs/architecture.md");
}

#[test]
fn rooms_never_import_what_they_must_not() {
    let c = Crate::read();
    let rg = room_graph(&c);
    let mut findings = Vec::new();
    for (from, to, why) in NEVER {
        for a in rg.get(*from).and_then(|t| t.get(*to)).into_iter().flatten() {
            findings.push(format!("`{from}` imports `{to}` ({why}): {a}"));
        }
    }
    for from in FLIGHT_STACK {
        for to in NOT_FOR_THE_FLIGHT_STACK {
            for a in rg.get(*from).and_then(|t| t.get(*to)).into_iter().flatten() {
                findings.push(format!(
                    "the flight stack (`{from}`) imports `{to}`: it sees only sensor readings: {a}"
                ));
            }
        }
    }
    fail_on(findings, "forbidden import(s)");
}

/// `a::b` as tokens at `i` (`a::` : `a` followed by `::`).
fn path_at(t: &[Token], i: usize, path: &str) -> bool {
    let open = path.ends_with("::");
    let segs: Vec<&str> = path.trim_end_matches("::").split("::").collect();
    segs.iter().enumerate().all(|(k, s)| {
        let at = i + 2 * k;
        let last = k + 1 == segs.len();
        t.get(at).is_some_and(|tok| tok.is_ident(s)) && (last && !open || t.get(at + 1).is_some_and(Token::is_sep))
    })
}

/// Where tokens name a runtime, the protocol, a clock or the global RNG:
/// (line, the name, what it is).
fn impure_names(t: &[Token]) -> Vec<(usize, &'static str, &'static str)> {
    let mut found = Vec::new();
    for i in 0..t.len() {
        for &(pat, what) in IMPURE {
            if path_at(t, i, pat) && !(i > 0 && t[i - 1].is_sep()) {
                found.push((t[i].line, pat, what));
            }
        }
    }
    found
}

/// Where tokens name a room the flight stack must not see (as a path
/// segment or in a `use` group) or a `SIM_*` parameter: (line, what).
fn world_names(t: &[Token]) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for i in 0..t.len() {
        let near_sep = (i > 0 && t[i - 1].is_sep()) || t.get(i + 1).is_some_and(Token::is_sep);
        let in_group = i > 0
            && (t[i - 1].is_punct('{') || t[i - 1].is_punct(','))
            && t.get(i + 1).is_some_and(|n| n.is_punct(',') || n.is_punct('}'));
        match &t[i].tok {
            Tok::Ident(s) if NOT_FOR_THE_FLIGHT_STACK.contains(&s.as_str()) && (near_sep || in_group) => {
                found.push((t[i].line, format!("`{s}`")))
            }
            Tok::Ident(s) if s.starts_with("SIM_") => found.push((t[i].line, format!("the world's parameter {s}"))),
            Tok::Str(s) if s.starts_with("SIM_") => found.push((t[i].line, format!("the world's parameter \"{s}\""))),
            _ => {}
        }
    }
    found
}

#[test]
fn pure_floors_use_no_runtime_protocol_clock_or_global_rng() {
    let c = Crate::read();
    let rooms = table();
    let mut findings = Vec::new();
    for f in &c.files {
        let Some(room) = rooms.get(&f.room) else { continue };
        if room.floor > PURE_UP_TO_FLOOR {
            continue;
        }
        for (line, pat, what) in impure_names(&f.tokens) {
            findings.push(format!(
                "{}:{line}: `{pat}` ({what}) in `{}`, floor {}",
                f.name, f.room, room.floor
            ));
        }
    }
    fail_on(
        findings,
        &format!("use(s) of a runtime, the protocol, a clock or the global RNG on floors 1-{PURE_UP_TO_FLOOR}"),
    );
}

#[test]
fn the_flight_stack_names_no_world_and_no_sim_parameter() {
    let c = Crate::read();
    let mut findings = Vec::new();
    for f in c.files.iter().filter(|f| FLIGHT_STACK.contains(&f.room.as_str())) {
        for (line, what) in world_names(&f.tokens) {
            findings.push(format!("{}:{line}: names {what}", f.name));
        }
    }
    fail_on(
        findings,
        "place(s) where the flight stack reaches into the simulated world (give it a sensor reading instead)",
    );
}

// ---------------------------------------------------------------- the checker's own tests

#[test]
fn the_lexer_drops_comments_strings_and_test_items() {
    let t = drop_test_items(lex(
        "use a::b; // crate::x\n/* crate::y /* nested */ */ let s = \"crate::z\"; let r = r#\"q\"#; let c = '\"'; let q = '\\''; fn f<'a>() {}\n#[cfg(test)]\nmod tests { use crate::w; }\nfn g() {}",
    ));
    let idents: Vec<_> = t.iter().filter_map(Token::ident).collect();
    assert_eq!(
        idents,
        [
            "use", "a", "b", "let", "s", "let", "r", "let", "c", "let", "q", "fn", "f", "fn", "g"
        ]
    );
    assert!(t.iter().any(|k| k.tok == Tok::Str("crate::z".into())));
    assert_eq!(t.last().unwrap().line, 5);
}

#[test]
fn use_trees_flatten_with_groups_self_and_renames() {
    let t = lex("crate::a::{self, b::{C, D as E}, f::*};");
    let mut out = Vec::new();
    use_leaves(&t, 0, &[], &mut out);
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    assert_eq!(
        out,
        vec![
            (s(&["crate", "a"]), Some("a".into())),
            (s(&["crate", "a", "b", "C"]), Some("C".into())),
            (s(&["crate", "a", "b", "D"]), Some("E".into())),
            (s(&["crate", "a", "f"]), None),
        ]
    );
}

#[test]
fn circles_are_found_and_walked() {
    let g: BTreeMap<String, BTreeMap<String, BTreeSet<String>>> =
        [("a", "b", "X"), ("b", "c", "Y"), ("c", "a", "Z"), ("c", "d", "W")]
            .into_iter()
            .fold(BTreeMap::new(), |mut g, (a, b, n)| {
                g.entry(a.to_string())
                    .or_default()
                    .entry(b.to_string())
                    .or_default()
                    .insert(n.to_string());
                g
            });
    let found = describe_circles(&g, "files");
    assert_eq!(found.len(), 1);
    assert!(
        found[0].starts_with("a circle of files: a -> b (X) -> c (Y) -> a (Z)"),
        "{}",
        found[0]
    );
}

#[test]
fn impure_and_world_names_are_found_in_code_only() {
    let t = lex(
        "// tokio, std::time\nuse std::time::Instant;\nlet n = Instant::now();\nmavlink::x(); a::mavlink::y();\nlet s = \"thread_rng\";",
    );
    let found: Vec<_> = impure_names(&t).into_iter().map(|(l, p, _)| (l, p)).collect();
    assert_eq!(found, [(2, "std::time"), (3, "Instant::now"), (4, "mavlink::")]);
    let t = lex("use crate::{sim, signals};\nlet sim = 1; lockstep::go(); p(Param::SIM_X, \"SIM_Y\");");
    let found: Vec<_> = world_names(&t).into_iter().map(|(l, _)| l).collect();
    assert_eq!(found, [1, 2, 2, 2]);
}
