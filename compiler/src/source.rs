//! Source files and spans.
//!
//! Every file the compiler reads (the main shader, every `#include`d header, and the text that `-D`
//! definitions and predefined macros come from) is registered in a [`SourceMap`] and gets a
//! [`FileId`]. A [`Span`] is a byte range inside one file. Tokens keep the span of the text they came
//! from through includes and macro expansion, so a diagnostic always names the file, line and column
//! the user wrote.
//!
//! Invariant: a `Span`'s `start <= end <= len(file)` for the file it names; spans are produced only by
//! the lexer (over real file text) and by [`Span::to`], which never mixes two files.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Identifies one file in a [`SourceMap`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default, serde::Serialize, serde::Deserialize)]
pub struct FileId(pub u32);

/// A byte range in one source file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
pub struct Span {
    pub file: FileId,
    pub start: u32,
    pub end: u32,
}

impl Span {
    pub fn new(file: FileId, start: u32, end: u32) -> Span {
        Span { file, start, end }
    }

    /// The smallest span covering `self` and `other`. Spans in different files, or an `other` that
    /// lies before `self` (possible after macro expansion), leave `self` unchanged: a diagnostic then
    /// points at the start of the construct rather than at a meaningless range.
    pub fn to(self, other: Span) -> Span {
        if self.file != other.file || other.end < self.start {
            return self;
        }
        Span { file: self.file, start: self.start.min(other.start), end: self.end.max(other.end) }
    }

    pub fn range(self) -> std::ops::Range<usize> {
        self.start as usize..self.end as usize
    }
}

/// One source file: its name as the user should see it, and its text.
#[derive(Debug)]
pub struct SourceFile {
    /// The path as it was found (relative paths stay relative, as the user typed them).
    pub name: String,
    /// The path used to resolve `#include "..."` relative to this file; `None` for virtual files.
    pub path: Option<PathBuf>,
    pub text: Arc<str>,
    line_starts: Arc<[u32]>,
}

fn line_starts(text: &str) -> Arc<[u32]> {
    // memchr finds the newlines with SIMD; the front end's speed depends on it.
    std::iter::once(0u32).chain(memchr::memchr_iter(b'\n', text.as_bytes()).map(|i| i as u32 + 1)).collect()
}

impl SourceFile {
    pub fn new(name: String, path: Option<PathBuf>, text: Arc<str>) -> SourceFile {
        let line_starts = line_starts(&text);
        SourceFile { name, path, text, line_starts }
    }

    /// The byte offset of every line start (shared by files with the same text).
    pub fn line_starts(&self) -> &Arc<[u32]> {
        &self.line_starts
    }

    /// Zero-based line index containing byte `offset`.
    pub fn line_index(&self, offset: u32) -> usize {
        match self.line_starts.binary_search(&offset) {
            Ok(i) => i,
            Err(i) => i - 1,
        }
    }

    pub fn line_start(&self, line: usize) -> Option<u32> {
        self.line_starts.get(line).copied()
    }

    pub fn line_count(&self) -> usize {
        self.line_starts.len()
    }

    /// One-based line and column (in characters) of `offset`.
    pub fn line_col(&self, offset: u32) -> (usize, usize) {
        let line = self.line_index(offset);
        let start = self.line_starts[line] as usize;
        let end = (offset as usize).min(self.text.len());
        let col = self.text.get(start..end).map(|s| s.chars().count()).unwrap_or(end - start);
        (line + 1, col + 1)
    }
}

/// All files of one compilation.
#[derive(Debug, Default)]
pub struct SourceMap {
    files: Vec<SourceFile>,
}

impl SourceMap {
    pub fn new() -> SourceMap {
        SourceMap::default()
    }

    pub fn add(&mut self, name: impl Into<String>, path: Option<PathBuf>, text: impl Into<Arc<str>>) -> FileId {
        let id = FileId(self.files.len() as u32);
        self.files.push(SourceFile::new(name.into(), path, text.into()));
        id
    }

    /// Registers a file whose text and line starts are already known (a cached header).
    pub fn add_shared(&mut self, name: String, path: Option<PathBuf>, text: Arc<str>, lines: Arc<[u32]>) -> FileId {
        let id = FileId(self.files.len() as u32);
        self.files.push(SourceFile { name, path, text, line_starts: lines });
        id
    }

    /// Registers an in-memory file (a test input, the command line's `-D` text).
    pub fn add_virtual(&mut self, name: impl Into<String>, text: impl Into<Arc<str>>) -> FileId {
        self.add(name, None, text)
    }

    /// Reads a file from disk. Invalid UTF-8 is replaced rather than refused: shader files from old
    /// collections are often Latin-1 in their comments.
    pub fn load(&mut self, path: &Path) -> std::io::Result<FileId> {
        let text = read_source_text(path)?;
        Ok(self.add(path.display().to_string(), Some(path.to_path_buf()), text))
    }

    pub fn get(&self, id: FileId) -> &SourceFile {
        &self.files[id.0 as usize]
    }

    pub fn files(&self) -> impl Iterator<Item = (FileId, &SourceFile)> {
        self.files.iter().enumerate().map(|(i, f)| (FileId(i as u32), f))
    }

    pub fn text(&self, span: Span) -> &str {
        self.get(span.file).text.get(span.range()).unwrap_or("")
    }

    /// `file:line:col` of the start of `span`.
    pub fn location(&self, span: Span) -> Location<'_> {
        let file = self.get(span.file);
        let (line, column) = file.line_col(span.start);
        Location { file: &file.name, line, column }
    }
}

/// A human-readable position: file name, one-based line and column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location<'a> {
    pub file: &'a str,
    pub line: usize,
    pub column: usize,
}

impl fmt::Display for Location<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}", self.file, self.line, self.column)
    }
}

impl<'a> codespan_reporting::files::Files<'a> for SourceMap {
    type FileId = FileId;
    type Name = &'a str;
    type Source = &'a str;

    fn name(&'a self, id: FileId) -> Result<&'a str, codespan_reporting::files::Error> {
        self.files.get(id.0 as usize).map(|f| f.name.as_str()).ok_or(codespan_reporting::files::Error::FileMissing)
    }

    fn source(&'a self, id: FileId) -> Result<&'a str, codespan_reporting::files::Error> {
        self.files.get(id.0 as usize).map(|f| &*f.text).ok_or(codespan_reporting::files::Error::FileMissing)
    }

    fn line_index(&'a self, id: FileId, byte_index: usize) -> Result<usize, codespan_reporting::files::Error> {
        let file = self.files.get(id.0 as usize).ok_or(codespan_reporting::files::Error::FileMissing)?;
        Ok(file.line_index(byte_index as u32))
    }

    fn line_range(
        &'a self,
        id: FileId,
        line_index: usize,
    ) -> Result<std::ops::Range<usize>, codespan_reporting::files::Error> {
        let file = self.files.get(id.0 as usize).ok_or(codespan_reporting::files::Error::FileMissing)?;
        let start = file
            .line_start(line_index)
            .ok_or(codespan_reporting::files::Error::LineTooLarge { given: line_index, max: file.line_count() - 1 })?
            as usize;
        let end = file.line_start(line_index + 1).map(|s| s as usize).unwrap_or(file.text.len());
        Ok(start..end)
    }
}

/// A source file's text as the compiler reads it: invalid UTF-8 is replaced rather than refused
/// (shader files from old collections are often Latin-1 in their comments).
pub fn read_source_text(path: &Path) -> std::io::Result<String> {
    let bytes = std::fs::read(path)?;
    Ok(match String::from_utf8(bytes) {
        Ok(s) => s,
        Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
    })
}
