//! Included and imported files read and parsed ahead, on other threads:
//! pbrt-v4 added `Import` so that a scene's files can be parsed in
//! parallel, and production scenes pull hundreds of files in with it. The
//! builder takes directives through a window that looks ahead of the one
//! it applies; every `Include` or `Import` seen there starts its file's read
//! and parse (syntax only) at once, and the builder picks up the parsed
//! directives when it gets there. Directives are still applied one by one
//! in file order, so the scene, its warnings and its first error are the
//! ones a serial load gives.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};

use crate::error::{FileLoc, SceneError};

use super::parser::{Directive, Parser, Statement};
use super::tokenizer::Tokenizer;

/// Directives a file is parsed ahead of the one applied: room for many
/// `Import`s in flight, and little memory.
const LOOKAHEAD: usize = 256;

/// One file whose directives the builder applies.
pub(super) struct Source {
    input: Input,
    ahead: VecDeque<Ahead>,
    ended: bool,
    /// As messages name it.
    pub file: Arc<str>,
    /// For cycle checks; `None` for text that is not a file.
    pub canonical: Option<PathBuf>,
}

enum Input {
    Live(Parser),
    /// Parsed ahead: the directives, then the syntax error that ended them.
    Parsed(std::vec::IntoIter<Directive>, Option<SceneError>),
}

/// The next directive of a [`Source`].
pub(super) enum Next {
    Directive(Directive),
    /// An `Include` or `Import`: its file, being read and parsed.
    Include(Directive, Arc<Prefetch<Result<Included, SceneError>>>),
}

enum Ahead {
    Next(Next),
    Error(SceneError),
}

/// An included file, read and parsed.
pub(super) struct Included {
    pub source: Source,
}

impl Source {
    /// The file `parser` reads.
    pub fn live(parser: Parser, canonical: Option<PathBuf>) -> Self {
        let file = Arc::from(parser.file());
        Source { input: Input::Live(parser), ahead: VecDeque::new(), ended: false, file, canonical }
    }

    /// The next directive (`None` at the end), reading further ahead
    /// first; files named by `Include` and `Import` resolve against
    /// `base_dir` and start reading as soon as they are seen.
    pub fn next(&mut self, base_dir: &Path) -> Result<Option<Next>, SceneError> {
        while self.ahead.len() < LOOKAHEAD && !self.ended {
            let read = match &mut self.input {
                Input::Live(parser) => parser.next_directive(),
                Input::Parsed(directives, error) => match directives.next() {
                    Some(d) => Ok(Some(d)),
                    None => error.take().map_or(Ok(None), Err),
                },
            };
            match read {
                Ok(Some(d)) => self.ahead.push_back(Ahead::Next(prefetch_includes(d, base_dir))),
                Ok(None) => self.ended = true,
                Err(e) => {
                    self.ahead.push_back(Ahead::Error(e));
                    self.ended = true;
                }
            }
        }
        match self.ahead.pop_front() {
            None => Ok(None),
            Some(Ahead::Next(next)) => Ok(Some(next)),
            Some(Ahead::Error(e)) => Err(e),
        }
    }
}

/// `d`, with its file's read and parse started if it includes one.
fn prefetch_includes(d: Directive, base_dir: &Path) -> Next {
    let file = match &d.statement {
        Statement::Include(f) | Statement::Import(f) => f.clone(),
        _ => return Next::Directive(d),
    };
    let (loc, base_dir) = (d.loc.clone(), base_dir.to_path_buf());
    let budget = crate::input::current_budget();
    let read = move || match budget {
        Some(b) => crate::input::with_budget(b, || read_included(&file, &loc, &base_dir)),
        None => read_included(&file, &loc, &base_dir),
    };
    Next::Include(d, Prefetch::spawn(Box::new(read)))
}

/// Reads and parses the file `Include`/`Import "file"` at `loc` names.
fn read_included(file: &str, loc: &FileLoc, base_dir: &Path) -> Result<Included, SceneError> {
    let path = crate::input::beside(base_dir, file)
        .map_err(|e| SceneError::caused_by(loc, format!("Include: {e}"), e))?;
    let canonical = path.canonicalize().map_err(|e| {
        SceneError::caused_by(loc, format!("cannot read included file '{}': {e}", path.display()), e)
    })?;
    let bytes = super::read_scene_file(&path)
        .map_err(|e| SceneError::caused_by(loc, format!("Include '{}': {e}", path.display()), e))?;
    let mut parser = Parser::new(Tokenizer::new(path.display().to_string(), bytes)?);
    let mut directives = Vec::new();
    let error = loop {
        match parser.next_directive() {
            Ok(Some(d)) => directives.push(d),
            Ok(None) => break None,
            Err(e) => break Some(e),
        }
    };
    let file = Arc::from(parser.file());
    let input = Input::Parsed(directives.into_iter(), error);
    Ok(Included {
        source: Source { input, ahead: VecDeque::new(), ended: false, file, canonical: Some(canonical) },
    })
}

type Work<T> = Box<dyn FnOnce() -> T + Send>;

/// Work started on the thread pool whose result one caller takes. The
/// taker runs the work itself if no worker has started it, so waiting
/// never deadlocks, even on a pool of one thread that the taker occupies.
pub(super) struct Prefetch<T> {
    work: Mutex<Option<Work<T>>>,
    result: Mutex<Option<T>>,
    ready: Condvar,
}

impl<T: Send + 'static> Prefetch<T> {
    fn spawn(work: Work<T>) -> Arc<Self> {
        let p = Arc::new(Prefetch {
            work: Mutex::new(Some(work)),
            result: Mutex::new(None),
            ready: Condvar::new(),
        });
        let worker = p.clone();
        rayon::spawn(move || worker.run());
        p
    }

    fn run(&self) {
        let work = self.work.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some(work) = work {
            let result = work();
            *self.result.lock().unwrap_or_else(|e| e.into_inner()) = Some(result);
            self.ready.notify_all();
        }
    }

    /// The result, waiting for it (or making it) as needed.
    pub fn take(&self) -> T {
        self.run();
        let mut result = self.result.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(r) = result.take() {
                return r;
            }
            result = self.ready.wait(result).unwrap_or_else(|e| e.into_inner());
        }
    }
}
