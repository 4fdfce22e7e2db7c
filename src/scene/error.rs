//! Errors of scene loading: every message names the file, the key, the value and the reason.

use std::fmt;
use std::path::{Path, PathBuf};

/// One broken rule: `materials.steel.poisson_ratio = 0.7: must be in (-1, 0.5)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// Dotted key path, e.g. `particles[3].radius_m`.
    pub key: String,
    /// The offending value as written (or derived), e.g. `-0.001`.
    pub value: String,
    /// Why it is rejected.
    pub reason: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} = {}: {}", self.key, self.value, self.reason)
    }
}

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("cannot read scene file {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// TOML syntax, unknown key, missing key or wrong type.
    #[error("{}{}{message}", file_prefix(path.as_deref()), key_prefix(key))]
    Parse {
        /// The file, once known.
        path: Option<PathBuf>,
        /// Dotted path of the key where deserialization stopped (empty for syntax errors).
        key: String,
        /// The parser's message (with line and column for syntax errors).
        message: String,
    },
    /// Values out of range or inconsistent with each other; all of them are listed.
    #[error("{}invalid scene ({} problem{}):\n{}", file_prefix(path.as_deref()), violations.len(),
        if violations.len() == 1 { "" } else { "s" },
        violations.iter().map(|v| format!("  - {v}")).collect::<Vec<_>>().join("\n"))]
    Invalid {
        /// The file, once known.
        path: Option<PathBuf>,
        /// Every violation found.
        violations: Vec<Violation>,
    },
}

fn file_prefix(path: Option<&Path>) -> String {
    path.map(|p| format!("{}: ", p.display()))
        .unwrap_or_default()
}

fn key_prefix(key: &str) -> String {
    if key.is_empty() || key == "." {
        String::new()
    } else {
        format!("key `{key}`: ")
    }
}

impl SceneError {
    /// Attaches the file name to a parse or validation error.
    #[must_use]
    pub fn in_file(self, file: &Path) -> Self {
        match self {
            Self::Parse { key, message, .. } => Self::Parse {
                path: Some(file.to_owned()),
                key,
                message,
            },
            Self::Invalid { violations, .. } => Self::Invalid {
                path: Some(file.to_owned()),
                violations,
            },
            read @ Self::Read { .. } => read,
        }
    }

    /// The violations of an [`SceneError::Invalid`] error (empty otherwise).
    #[must_use]
    pub fn violations(&self) -> &[Violation] {
        match self {
            Self::Invalid { violations, .. } => violations,
            _ => &[],
        }
    }
}
