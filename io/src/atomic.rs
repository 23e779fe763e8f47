//! Files and directories that appear whole or not at all: written under a temporary name
//! beside the target and renamed into place, so that an error or a crash never leaves a
//! half-written result under the final name.

use std::path::Path;

use anyhow::Context as _;

/// The directory `path` is written in: its parent, or "." for a bare file name.
pub fn parent_dir(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Writes `text` to `path` through a temporary file in the same directory.
pub fn write_atomically(path: &Path, text: &str) -> anyhow::Result<()> {
    let dir = parent_dir(path);
    let tmp = dir.join(format!(
        ".{}.tmp",
        path.file_name().and_then(|n| n.to_str()).unwrap_or("plot")
    ));
    std::fs::write(&tmp, text).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| {
        let _ = std::fs::remove_file(&tmp);
        format!("renaming {} to {}", tmp.display(), path.display())
    })
}

/// Fills a new directory `dir` through `fill`, which writes into a temporary sibling
/// directory that is then renamed to `dir`: an error leaves nothing behind (the temporary
/// directory is removed) and `dir` never exists half-written. Refuses an existing `dir`.
pub fn write_dir_atomically(
    dir: &Path,
    fill: impl FnOnce(&Path) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    if dir.exists() {
        anyhow::bail!(
            "{}: the directory exists already; remove it or choose a new one",
            dir.display()
        );
    }
    let parent = parent_dir(dir);
    let name = dir
        .file_name()
        .and_then(|n| n.to_str())
        .with_context(|| format!("{}: the directory needs a name", dir.display()))?;
    let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp)
            .with_context(|| format!("removing the stale {}", tmp.display()))?;
    }
    std::fs::create_dir_all(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
    let result = fill(&tmp).and_then(|()| {
        std::fs::rename(&tmp, dir)
            .with_context(|| format!("renaming {} to {}", tmp.display(), dir.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_fill_leaves_no_directory() {
        let base = std::env::temp_dir().join(format!("forcemap-atomic-{}", std::process::id()));
        let dir = base.join("report");
        std::fs::create_dir_all(&base).unwrap();
        let e = write_dir_atomically(&dir, |tmp| {
            write_atomically(&tmp.join("a.svg"), "<svg/>")?;
            anyhow::bail!("drawing failed")
        });
        assert!(e.is_err());
        assert!(!dir.exists());
        assert_eq!(std::fs::read_dir(&base).unwrap().count(), 0);
        write_dir_atomically(&dir, |tmp| write_atomically(&tmp.join("a.svg"), "<svg/>")).unwrap();
        assert!(dir.join("a.svg").is_file());
        assert!(write_dir_atomically(&dir, |_| Ok(())).is_err());
        std::fs::remove_dir_all(&base).unwrap();
    }
}
