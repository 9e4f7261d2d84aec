//! The shell blocks of `README.md` and `docs/*.md` run as written. A fenced block whose info
//! string is exactly `sh` is a quick one: it runs here with `bash -euo pipefail`, in a scratch
//! folder that links the repository's top-level folders and has an empty `out/`, with the
//! `stereosplat` binary first on `PATH`. Every other shell block is marked
//! `sh long-running` (with a comment saying why) and is only checked to be marked so.

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
