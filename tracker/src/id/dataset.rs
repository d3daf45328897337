//! A folder of labelled recordings: `DIR/<class>/*.wav`, one subfolder per class (a class
//! `none` for recordings without a drone). Files other than `.wav` are ignored; a class folder
//! without any `.wav`, WAV files directly in `DIR`, or a `DIR` without class folders is an
//! error naming the folder.
use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};

/// One class: its name (the folder's) and its recordings, sorted by path.
#[derive(Clone, Debug, PartialEq)]
pub struct Class {
    /// Class name.
    pub name: String,
    /// Its WAV files.
    pub files: Vec<PathBuf>,
}

fn is_wav(p: &Path) -> bool {
    p.is_file() && p.extension().is_some_and(|e| e.eq_ignore_ascii_case("wav"))
}

/// Lists the classes of `dir`, sorted by name.
pub fn scan(dir: &Path) -> anyhow::Result<Vec<Class>> {
    if !dir.is_dir() {
        bail!("{}: not a folder (expected one subfolder of WAV files per class)", dir.display());
    }
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot list {}", dir.display()))?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()
        .with_context(|| format!("cannot list {}", dir.display()))?;
    entries.sort();
    if let Some(w) = entries.iter().find(|p| is_wav(p)) {
        bail!(
            "{}: WAV files directly in the dataset folder ({}); put each class's recordings in a \
             subfolder named after the class (e.g. {}/none/)",
            dir.display(),
            w.display(),
            dir.display()
        );
    }
    let mut classes = Vec::new();
    for sub in entries.into_iter().filter(|p| p.is_dir()) {
        let name = sub
            .file_name()
            .and_then(|n| n.to_str())
            .with_context(|| format!("{}: folder name is not UTF-8", sub.display()))?
            .to_string();
        if name.starts_with('.') {
            continue;
        }
        let mut files: Vec<PathBuf> = std::fs::read_dir(&sub)
            .with_context(|| format!("cannot list {}", sub.display()))?
            .map(|e| e.map(|e| e.path()))
            .collect::<Result<Vec<_>, _>>()
            .with_context(|| format!("cannot list {}", sub.display()))?
            .into_iter()
            .filter(|p| is_wav(p))
            .collect();
        if files.is_empty() {
            bail!("{}: class `{name}` has no .wav recordings", sub.display());
        }
        files.sort();
        classes.push(Class { name, files });
    }
    if classes.is_empty() {
        bail!("{}: no class folders (expected DIR/<class>/*.wav)", dir.display());
    }
    Ok(classes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_errors_name_the_problem() {
        let dir = std::env::temp_dir().join(format!("aim-id-dataset-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        assert!(scan(&dir).unwrap_err().to_string().contains("not a folder"));
        std::fs::create_dir_all(dir.join("b")).unwrap();
        std::fs::create_dir_all(dir.join("a")).unwrap();
        std::fs::write(dir.join("a/x.WAV"), b"").unwrap();
        std::fs::write(dir.join("a/notes.txt"), b"").unwrap();
        let e = scan(&dir).unwrap_err().to_string();
        assert!(e.contains("class `b` has no .wav"), "{e}");
        std::fs::write(dir.join("b/y.wav"), b"").unwrap();
        let c = scan(&dir).unwrap();
        assert_eq!(c.len(), 2);
        assert_eq!((c[0].name.as_str(), c[0].files.len()), ("a", 1));
        std::fs::write(dir.join("stray.wav"), b"").unwrap();
        assert!(scan(&dir).unwrap_err().to_string().contains("directly in the dataset folder"));
        std::fs::remove_dir_all(&dir).unwrap();
        std::fs::create_dir_all(&dir).unwrap();
        assert!(scan(&dir).unwrap_err().to_string().contains("no class folders"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
