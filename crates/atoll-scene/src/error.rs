//! The error type of the loaders and the warnings they collect.
//!
//! Both carry a source location so that every message a user sees points at
//! the offending statement: `file:line:col: message` (pbrt-v4's `FileLoc`).
//! Narrower failures (an image that cannot be decoded, a mesh that does not
//! hold together) have their own types beside the code that reports them;
//! the loaders wrap them into a [`SceneError`] that keeps them as its source.

use std::fmt;
use std::sync::Arc;

/// A position in a scene file. Lines and columns count from 1; line 0 means
/// "the file as a whole" (e.g. it could not be opened).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileLoc {
    /// The file as the user named it (or as it was resolved for `Include`).
    pub file: Arc<str>,
    /// Line, from 1 (0: the whole file).
    pub line: u32,
    /// Column in characters, from 1.
    pub col: u32,
}

impl FileLoc {
    /// A location at `line`:`col` of `file`.
    pub fn new(file: impl Into<Arc<str>>, line: u32, col: u32) -> Self {
        FileLoc { file: file.into(), line, col }
    }

    /// The location of a whole file (no line), for errors such as "cannot open".
    pub fn whole_file(file: impl Into<Arc<str>>) -> Self {
        FileLoc { file: file.into(), line: 0, col: 0 }
    }
}

impl fmt::Display for FileLoc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}", self.file)
        } else {
            write!(f, "{}:{}:{}", self.file, self.line, self.col)
        }
    }
}

/// Why a scene could not be loaded. Displays as `file:line:col: message`
/// (just `file: message` when the problem concerns the whole file).
///
/// `message` is complete on its own (it already says what a wrapped error
/// says), so a user reading only the top-level error learns everything;
/// `source` keeps the wrapped error for callers that inspect the chain.
/// Equality compares the location and the message only.
#[derive(Clone, Debug)]
pub struct SceneError {
    /// The file, as named by the user or resolved for `Include`.
    pub file: String,
    /// Line, from 1 (0: the whole file).
    pub line: u32,
    /// Column, from 1.
    pub col: u32,
    /// What is wrong.
    pub message: String,
    /// The failure underneath (an I/O or decoding error), if there is one.
    /// Shared so that the error stays cheap to clone.
    pub source: Option<Arc<dyn std::error::Error + Send + Sync>>,
}

impl SceneError {
    /// An error at `loc`.
    pub fn at(loc: &FileLoc, message: impl Into<String>) -> Self {
        SceneError {
            file: loc.file.to_string(),
            line: loc.line,
            col: loc.col,
            message: message.into(),
            source: None,
        }
    }

    /// An error at `loc` caused by `source`; `message` should say what
    /// `source` says too (it is what users see).
    pub fn caused_by(
        loc: &FileLoc,
        message: impl Into<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        SceneError { source: Some(Arc::new(source)), ..SceneError::at(loc, message) }
    }

    /// Where the error is, as a [`FileLoc`].
    pub fn loc(&self) -> FileLoc {
        FileLoc::new(self.file.as_str(), self.line, self.col)
    }
}

impl PartialEq for SceneError {
    fn eq(&self, other: &Self) -> bool {
        (&self.file, self.line, self.col, &self.message)
            == (&other.file, other.line, other.col, &other.message)
    }
}

impl Eq for SceneError {}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.loc(), self.message)
    }
}

// By hand rather than derived: the source must be the wrapped error itself
// (so callers can downcast it), not the `Arc` around it.
impl std::error::Error for SceneError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source.as_deref().map(|e| e as &(dyn std::error::Error + 'static))
    }
}

/// Something in a scene that atoll ignored or approximated. Loaders collect
/// these and also emit each one with `tracing::warn!`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Warning {
    /// The file, as named by the user or resolved for `Include`.
    pub file: String,
    /// Line, from 1 (0: the whole file).
    pub line: u32,
    /// Column, from 1.
    pub col: u32,
    /// What was ignored or approximated.
    pub message: String,
}

impl Warning {
    /// A warning at `loc`.
    pub fn at(loc: &FileLoc, message: impl Into<String>) -> Self {
        Warning { file: loc.file.to_string(), line: loc.line, col: loc.col, message: message.into() }
    }
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let loc = FileLoc::new(self.file.as_str(), self.line, self.col);
        write!(f, "{loc}: {}", self.message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_has_file_line_col() {
        let e = SceneError::at(&FileLoc::new("a.pbrt", 3, 7), "bad number");
        assert_eq!(e.to_string(), "a.pbrt:3:7: bad number");
        let w = Warning::at(&FileLoc::new("b.pbrt", 1, 2), "ignored");
        assert_eq!(w.to_string(), "b.pbrt:1:2: ignored");
        let whole = SceneError::at(&FileLoc::whole_file("c.pbrt"), "cannot open");
        assert_eq!(whole.to_string(), "c.pbrt: cannot open");
    }

    #[test]
    fn wrapped_errors_stay_the_source() {
        use std::error::Error;
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "gone");
        let e = SceneError::caused_by(&FileLoc::whole_file("d.pbrt"), "cannot read scene file: gone", io);
        assert_eq!(e.to_string(), "d.pbrt: cannot read scene file: gone");
        let source = e.source().expect("a source");
        assert!(source
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::NotFound));
    }
}
