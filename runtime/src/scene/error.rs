//! The scene layer's one error type.
//!
//! Every error names the file it is about; parse errors add the 1-based line (and column where
//! the parser knows it). Nothing in the scene layer panics on bad input: malformed files,
//! out-of-range indices, NaN coordinates and empty meshes all end up here.

use std::fmt;
use std::path::{Path, PathBuf};

/// Where in a file something went wrong: the path and, when known, a 1-based line and column.
///
/// Displays as `path:line:column`, `path:line` or `path`, the form editors and terminals link.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file.
    pub path: PathBuf,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// 1-based column, when known.
    pub column: Option<usize>,
}

impl Location {
    /// The whole file.
    pub fn file(path: impl Into<PathBuf>) -> Self {
        Self { path: path.into(), line: None, column: None }
    }

    /// One line of the file.
    pub fn line(path: impl Into<PathBuf>, line: usize) -> Self {
        Self { path: path.into(), line: Some(line), column: None }
    }

    /// One position of the file.
    pub fn at(path: impl Into<PathBuf>, line: usize, column: usize) -> Self {
        Self { path: path.into(), line: Some(line), column: Some(column) }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(column) = self.column {
                write!(f, ":{column}")?;
            }
        }
        Ok(())
    }
}

/// Everything that can go wrong while building, loading or resolving a scene.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A file could not be read (missing, unreadable).
    #[error("{path}: {source}", path = .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A syntax error in an OBJ, MTL, JSON or TOML file.
    #[error("{location}: {message}")]
    Parse {
        /// File, line and column.
        location: Location,
        /// What is wrong, in words.
        message: String,
    },
    /// The file parsed but its content is unusable (NaN coordinates, empty mesh, a light with
    /// no power, an unknown material name, ...).
    #[error("{location}: {message}")]
    Invalid {
        /// File (and line, when it applies).
        location: Location,
        /// What is wrong, in words.
        message: String,
    },
    /// An image (texture or environment map) could not be decoded.
    #[error("{path}: cannot decode image: {message}", path = .path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// The decoder's message.
        message: String,
    },
    /// `--scene` matched no built-in name, manifest or scene folder.
    #[error(
        "unknown scene '{spec}': not a built-in scene, a manifest (*.toml), a glTF file (*.gltf, *.glb) or a \
         scene folder (with scene.obj, scene.glb or scene.gltf); built-in scenes: {}",
        .builtins.join(", ")
    )]
    UnknownScene {
        /// What the user asked for.
        spec: String,
        /// The built-in names, for the message.
        builtins: Vec<&'static str>,
    },
}

impl SceneError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io { path: path.to_path_buf(), source }
    }

    pub(crate) fn parse_at(path: &Path, line: usize, message: impl Into<String>) -> Self {
        Self::Parse { location: Location::line(path, line), message: message.into() }
    }

    pub(crate) fn invalid(path: &Path, message: impl Into<String>) -> Self {
        Self::Invalid { location: Location::file(path), message: message.into() }
    }

    pub(crate) fn invalid_at(path: &Path, line: usize, message: impl Into<String>) -> Self {
        Self::Invalid { location: Location::line(path, line), message: message.into() }
    }

    /// The location the error refers to, when it has one.
    pub fn location(&self) -> Option<Location> {
        match self {
            Self::Io { path, .. } | Self::Image { path, .. } => Some(Location::file(path)),
            Self::Parse { location, .. } | Self::Invalid { location, .. } => Some(location.clone()),
            Self::UnknownScene { .. } => None,
        }
    }
}

/// 1-based line and column of byte `offset` in `text` (for parsers that report byte spans).
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let line_start = before.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
    let column = String::from_utf8_lossy(&before[line_start..]).chars().count() + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_display_like_compilers() {
        assert_eq!(Location::file("a/b.obj").to_string(), "a/b.obj");
        assert_eq!(Location::line("a/b.obj", 7).to_string(), "a/b.obj:7");
        assert_eq!(Location::at("m.toml", 3, 9).to_string(), "m.toml:3:9");
    }

    #[test]
    fn byte_offsets_become_lines_and_columns() {
        let text = "ab\ncde\n\nf";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, 4), (2, 2));
        assert_eq!(line_column(text, 8), (4, 1));
        assert_eq!(line_column(text, 100), (4, 2));
    }

    #[test]
    fn unknown_scene_lists_builtins() {
        let e = SceneError::UnknownScene { spec: "nope".into(), builtins: vec!["cornell", "atrium"] };
        let m = e.to_string();
        assert!(m.contains("'nope'") && m.contains("cornell, atrium"), "{m}");
    }
}
