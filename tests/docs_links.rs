//! The documentation's links hold: every relative link in `README.md`,
//! `tests/README.md` (when present) and `docs/*.md` names a file or directory
//! that exists, and every `#anchor` names a heading of its target (GitHub's
//! slugs: lowercase, spaces to `-`, punctuation dropped, `-1`, `-2` for
//! repeated headings). The README stays a front page: at most 200 lines.
//! Links inside code (fenced blocks, inline backticks) are not links.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The most lines the README may have; the rest belongs in `docs/`.
const README_MAX_LINES: usize = 200;

/// A link as written: its line (from 1) and its target (`path#anchor`).
#[derive(Debug, PartialEq)]
struct Link {
    line: usize,
    target: String,
}

/// The lines of `text` with fenced code blocks blanked (kept as empty lines,
/// so line numbers stay right).
fn prose_lines(text: &str) -> Vec<String> {
    let mut fence: Option<String> = None;
    text.lines()
        .map(|line| {
            let t = line.trim_start();
            let marker: String = t.chars().take_while(|&c| c == '`' || c == '~').collect();
            match &fence {
                Some(open) => {
                    if marker.len() >= open.len() && marker.starts_with(&open[..1]) {
                        fence = None;
                    }
                    String::new()
                }
                None if marker.len() >= 3 && (marker.starts_with("```") || marker.starts_with("~~~")) => {
                    fence = Some(marker);
                    String::new()
                }
                None => line.to_string(),
            }
        })
        .collect()
}

/// `line` without its inline code spans (`` `...` ``).
fn without_code_spans(line: &str) -> String {
    let mut out = String::new();
    let mut rest = line;
    while let Some(start) = rest.find('`') {
        out.push_str(&rest[..start]);
        let ticks = rest[start..].chars().take_while(|&c| c == '`').count();
        let after = &rest[start + ticks..];
        match after.find(&"`".repeat(ticks)) {
            Some(end) => rest = &after[end + ticks..],
            None => {
                out.push_str(&rest[start..]);
                return out;
            }
        }
    }
    out.push_str(rest);
    out
}

/// Every inline link `[text](target)` and image `![alt](target)` and every
/// reference definition `[label]: target` of `text`, outside code.
fn links(text: &str) -> Vec<Link> {
    let mut found = Vec::new();
    for (i, line) in prose_lines(text).iter().enumerate() {
        let line = without_code_spans(line);
        let trimmed = line.trim_start();
        // a reference definition: `[label]: target` (the label's first `]`)
        if trimmed.starts_with('[')
            && let Some(close) = trimmed.find(']')
            && let Some(target) = trimmed[close + 1..].strip_prefix(':')
        {
            let target = target.split_whitespace().next().unwrap_or("");
            found.push(Link {
                line: i + 1,
                target: target.trim_matches(['<', '>']).to_string(),
            });
            continue;
        }
        let mut rest = line.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let end = after.find([')', ' ']).unwrap_or(after.len());
            let target = after[..end].trim_matches(['<', '>']);
            found.push(Link {
                line: i + 1,
                target: target.to_string(),
            });
            rest = &after[end..];
        }
    }
    found
}

/// GitHub's anchor for a heading's text: markup dropped, lowercase, every
/// character but letters, digits, `_`, `-` and spaces dropped, spaces to `-`.
fn slug(heading: &str) -> String {
    // a link in a heading keeps only its text
    let mut text = String::new();
    let mut rest = heading;
    while let Some(open) = rest.find('[') {
        match rest[open..]
            .find("](")
            .and_then(|m| rest[open + m..].find(')').map(|c| (m, c)))
        {
            Some((mid, close)) => {
                text.push_str(&rest[..open]);
                text.push_str(&rest[open + 1..open + mid]);
                rest = &rest[open + mid + close + 1..];
            }
            None => break,
        }
    }
    text.push_str(rest);
    text.to_lowercase()
        .chars()
        .filter(|&c| c.is_alphanumeric() || c == '_' || c == '-' || c == ' ')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of a Markdown text's headings (ATX `#` headings outside code),
/// repeated ones numbered as GitHub numbers them.
fn anchors(text: &str) -> Vec<String> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut out = Vec::new();
    for line in prose_lines(text) {
        let t = line.trim_start();
        let hashes = t.chars().take_while(|&c| c == '#').count();
        if !(1..=6).contains(&hashes) || !t[hashes..].starts_with(' ') {
            continue;
        }
        let base = slug(t[hashes..].trim().trim_end_matches('#').trim());
        let n = seen.entry(base.clone()).or_insert(0);
        out.push(if *n == 0 { base.clone() } else { format!("{base}-{n}") });
        *n += 1;
    }
    out
}

/// The broken links of `file` (text `text`), each as `file:line: link: why`;
/// `read` gives the text of another Markdown file (None: it does not exist).
fn broken_links(
    file: &Path,
    text: &str,
    exists: &dyn Fn(&Path) -> bool,
    read: &dyn Fn(&Path) -> Option<String>,
) -> Vec<String> {
    let dir = file.parent().unwrap_or(Path::new(""));
    let mut broken = Vec::new();
    for link in links(text) {
        let t = link.target.as_str();
        if t.is_empty() || t.contains("://") || t.starts_with("mailto:") {
            continue;
        }
        let (path, anchor) = match t.split_once('#') {
            Some((p, a)) => (p, Some(a)),
            None => (t, None),
        };
        let target: PathBuf = if path.is_empty() {
            file.to_path_buf()
        } else {
            dir.join(path)
        };
        let say = |why: String| format!("{}:{}: ({t}): {why}", file.display(), link.line);
        if !path.is_empty() && !exists(&target) {
            broken.push(say(format!("{} does not exist", target.display())));
            continue;
        }
        let Some(anchor) = anchor else { continue };
        if target.extension().is_none_or(|e| e != "md") {
            continue;
        }
        let body = if path.is_empty() {
            Some(text.to_string())
        } else {
            read(&target)
        };
        match body {
            Some(body) if anchors(&body).iter().any(|a| a == anchor) => {}
            Some(_) => broken.push(say(format!(
                "no heading of {} has the anchor #{anchor}",
                target.display()
            ))),
            None => broken.push(say(format!("cannot read {}", target.display()))),
        }
    }
    broken
}

/// The repository root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// README.md, tests/README.md if present, docs/*.md: paths relative to the root.
fn documents() -> Vec<PathBuf> {
    let root = root();
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/ exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .map(|p| p.strip_prefix(&root).unwrap().to_path_buf())
        .collect();
    docs.sort();
    let mut all = vec![PathBuf::from("README.md")];
    if root.join("tests/README.md").exists() {
        all.push(PathBuf::from("tests/README.md"));
    }
    all.extend(docs);
    all
}

#[test]
fn every_relative_link_and_anchor_of_the_docs_resolves() {
    let root = root();
    let exists = |p: &Path| root.join(p).exists();
    let read = |p: &Path| std::fs::read_to_string(root.join(p)).ok();
    let mut broken = Vec::new();
    let mut checked = 0;
    for doc in documents() {
        let text = std::fs::read_to_string(root.join(&doc)).unwrap();
        checked += links(&text).len();
        broken.extend(broken_links(&doc, &text, &exists, &read));
    }
    assert!(checked > 20, "only {checked} links found: is the link finder broken?");
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn the_readme_is_a_front_page_of_at_most_200_lines() {
    let text = std::fs::read_to_string(root().join("README.md")).unwrap();
    let n = text.lines().count();
    assert!(
        n <= README_MAX_LINES,
        "README.md: {n} lines, more than {README_MAX_LINES}: move the detail into a page under docs/"
    );
}

#[test]
fn slugs_follow_githubs_rules() {
    assert_eq!(
        slug("Mission tests in CI: pytest, replay, logs"),
        "mission-tests-in-ci-pytest-replay-logs"
    );
    assert_eq!(slug("One `pip install`"), "one-pip-install");
    assert_eq!(
        slug("3b. Flying after a rotor is lost"),
        "3b-flying-after-a-rotor-is-lost"
    );
    assert_eq!(
        slug("The `[campaign]` table: COM_ACT_FAIL_ACT"),
        "the-campaign-table-com_act_fail_act"
    );
    assert_eq!(slug("See [logs](logs.md) now"), "see-logs-now");
    assert_eq!(
        anchors("# A\n## A\n```\n# not a heading\n```\n### A?\n"),
        ["a", "a-1", "a-2"]
    );
}

#[test]
fn the_checker_names_file_line_and_link_of_a_broken_link() {
    let text = "# Top\n\nSee [ok](b.md#part), [gone](missing.md),\n[bad anchor](b.md#nowhere), [here](#top), [not here](#elsewhere).\n\n```\n[in code](nothing.md)\n```\n`[span](nothing.md)` [web](https://example.com/x.md)\n\n[ref]: nope.md\n";
    let exists = |p: &Path| p == Path::new("docs/b.md");
    let read = |p: &Path| (p == Path::new("docs/b.md")).then(|| "# B\n## Part\n".to_string());
    let broken = broken_links(Path::new("docs/a.md"), text, &exists, &read);
    assert_eq!(broken.len(), 4, "{broken:#?}");
    assert!(broken[0].starts_with("docs/a.md:3: (missing.md): "), "{}", broken[0]);
    assert!(broken[1].starts_with("docs/a.md:4: (b.md#nowhere): "), "{}", broken[1]);
    assert!(broken[2].starts_with("docs/a.md:4: (#elsewhere): "), "{}", broken[2]);
    assert!(broken[3].starts_with("docs/a.md:11: (nope.md): "), "{}", broken[3]);
}
