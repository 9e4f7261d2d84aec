//! The shell blocks of `README.md` and `docs/*.md` run as written. A fenced block whose info
//! string is exactly `sh` is a quick one: it runs here with `bash -euo pipefail`, in a scratch
//! folder that links the repository's top-level folders and has an empty `out/`, with the
//! `stereosplat` binary first on `PATH`. Every other shell block is marked
//! `sh long-running` (with a comment saying why) and is only checked to be marked so. And
//! every repository path the code and scripts cite (`docs/...`, `results/...`, `launch/...`)
//! exists.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::cli_support::temp_dir;

/// A fenced code block: its info string, its text and where it starts.
struct Block {
    info: String,
    text: String,
    file: PathBuf,
    line: usize,
}

/// The repository root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .unwrap()
}

/// `README.md` and every page under `docs/`, in name order.
fn pages() -> Vec<PathBuf> {
    let root = root();
    let mut pages = vec![root.join("README.md")];
    if let Ok(dir) = std::fs::read_dir(root.join("docs")) {
        let mut docs: Vec<PathBuf> = dir
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "md"))
            .collect();
        docs.sort();
        pages.extend(docs);
    }
    pages
}

/// The fenced blocks of `file` (backtick fences of three or more, at any indent).
fn blocks(file: &Path) -> Vec<Block> {
    let text = std::fs::read_to_string(file).unwrap();
    let mut out = Vec::new();
    let mut open: Option<(String, usize, String, usize)> = None;
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim_start();
        let ticks = trimmed.chars().take_while(|&c| c == '`').count();
        match &mut open {
            None if ticks >= 3 => {
                let info = trimmed[ticks..].trim().to_string();
                open = Some((info, i + 1, String::new(), ticks));
            }
            Some((_, _, _, n)) if ticks >= *n && trimmed[ticks..].trim().is_empty() => {
                let (info, start, body, _) = open.take().unwrap();
                out.push(Block {
                    info,
                    text: body,
                    file: file.to_path_buf(),
                    line: start,
                });
            }
            Some((_, _, body, _)) => {
                body.push_str(line);
                body.push('\n');
            }
            None => {}
        }
    }
    assert!(open.is_none(), "{}: an unclosed code fence", file.display());
    out
}

/// Whether a block holds shell commands (by its language word).
fn is_shell(info: &str) -> bool {
    matches!(
        info.split_whitespace().next(),
        Some("sh" | "bash" | "shell" | "console" | "zsh")
    )
}

/// A scratch folder linking the repository's top-level entries, with its own empty `out/`.
fn scratch(name: &str) -> PathBuf {
    let dir = temp_dir(name);
    std::fs::create_dir_all(dir.join("out")).unwrap();
    for entry in std::fs::read_dir(root()).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name();
        if name == "out" || name == "target" || name == ".git" {
            continue;
        }
        std::os::unix::fs::symlink(entry.path(), dir.join(&name)).unwrap();
    }
    dir
}

#[test]
fn every_shell_block_is_quick_or_marked_long_running() {
    for page in pages() {
        for b in blocks(&page).iter().filter(|b| is_shell(&b.info)) {
            let at = format!("{}:{}", b.file.display(), b.line);
            assert!(
                b.info == "sh" || b.info == "sh long-running",
                "{at}: a shell block is ```sh (run by this test) or ```sh long-running, not \
                 ```{}",
                b.info
            );
            if b.info == "sh long-running" {
                assert!(
                    b.text.trim_start().starts_with("# long-running"),
                    "{at}: a long-running block opens with `# long-running: why`"
                );
            }
        }
    }
}

#[test]
fn the_quick_shell_blocks_run() {
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_stereosplat"))
        .parent()
        .unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut ran = 0;
    for page in pages() {
        for (i, b) in blocks(&page).iter().filter(|b| b.info == "sh").enumerate() {
            let at = format!("{}:{}", b.file.display(), b.line);
            let stem = page.file_stem().unwrap().to_string_lossy().to_lowercase();
            let dir = scratch(&format!("doc-{stem}-{i}"));
            let run = Command::new("bash")
                .args(["-euo", "pipefail", "-c", &b.text])
                .current_dir(&dir)
                .env("PATH", &path)
                .output()
                .unwrap();
            assert!(
                run.status.success(),
                "{at}: the block failed\n{}\nstdout: {}\nstderr: {}",
                b.text,
                String::from_utf8_lossy(&run.stdout),
                String::from_utf8_lossy(&run.stderr)
            );
            let _ = std::fs::remove_dir_all(&dir);
            ran += 1;
        }
    }
    assert!(ran > 0, "the docs hold quick blocks");
}

/// Every file under `dir` (no `node_modules`, no `target`) whose name ends with one of
/// `endings`.
fn files_under(dir: &Path, endings: &[&str], out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().to_string();
        if path.is_dir() {
            if !matches!(name.as_str(), "node_modules" | "target" | ".git") {
                files_under(&path, endings, out);
            }
        } else if endings.iter().any(|e| name.ends_with(e)) {
            out.push(path);
        }
    }
}

#[test]
fn every_repository_path_the_code_cites_exists() {
    let root = root();
    let mut files = Vec::new();
    for dir in [
        "node/src",
        "node/tests",
        "model/src",
        "model/tests",
        "renderer/src",
        "ros2_bridge/src",
        "tests",
        "scripts",
        ".ci",
        "fuzz",
    ] {
        files_under(
            &root.join(dir),
            &[".rs", ".py", ".sh", "run", "setup"],
            &mut files,
        );
    }
    // A path of this repository; one written as another project's (preceded by "its" or by
    // a possessive, "rmw_zenoh's", on its line) is not checked.
    let cited = regex::Regex::new(
        r"(^|[^\w/.-])((?:docs|results|scripts|launch|view|model|node|renderer|tests)/[A-Za-z0-9_./-]+\.(?:md|json5|json|toml|py|sh|xml|yaml|csv|safetensors))",
    )
    .unwrap();
    let mut missing = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap_or_default();
        for (n, line) in text.lines().enumerate() {
            for c in cited.captures_iter(line) {
                let m = c.get(2).unwrap();
                let before = &line[..m.start()];
                if before.ends_with("'s `") || before.ends_with("its `") {
                    continue;
                }
                let path = m.as_str().trim_end_matches('.');
                if !root.join(path).exists() {
                    let at = file.strip_prefix(&root).unwrap_or(file).display();
                    missing.push(format!("{at}:{}: {path}", n + 1));
                }
            }
        }
    }
    assert!(files.len() > 100, "{} files read", files.len());
    assert!(
        missing.is_empty(),
        "cited but not in the repository:\n{}",
        missing.join("\n")
    );
}
