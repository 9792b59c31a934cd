//! RIB diagnostics drawn the way the compiler draws shader diagnostics (codespan-reporting): the
//! message, then the file, line and column and the line itself with the request underlined.
//!
//! A diagnostic whose file cannot be read back (a stream named `<...>`, a file changed or gone
//! since) or whose location is the file as a whole is written on one line, `file:line:col:
//! warning: message`, the form `Display` gives.

use super::{RibDiagnostic, Severity};
use codespan_reporting::diagnostic::{Diagnostic, Label};
use codespan_reporting::files::SimpleFiles;
use codespan_reporting::term::{self, termcolor::WriteColor};
use std::collections::HashMap;
use std::path::Path;

/// Writes `diagnostics` to `out` (coloured when `out` supports colour), reading each file they
/// name once.
pub fn write_diagnostics(diagnostics: &[RibDiagnostic], out: &mut dyn WriteColor) -> std::io::Result<()> {
    let mut files = SimpleFiles::new();
    let mut ids: HashMap<&Path, Option<usize>> = HashMap::new();
    let config = term::Config::default();
    for d in diagnostics {
        let id = *ids.entry(&d.loc.file).or_insert_with(|| {
            // A RIB file's comments may be in any 8-bit encoding; its requests read the same.
            let text = String::from_utf8_lossy(&std::fs::read(&d.loc.file).ok()?).into_owned();
            Some(files.add(d.loc.file.display().to_string(), text))
        });
        let span = id.and_then(|id| Some((id, span_at(files.get(id).ok()?.source(), d.loc.line, d.loc.column)?)));
        let Some((id, span)) = span else {
            writeln!(out, "{d}")?;
            continue;
        };
        // A multi-line message (a shader's own diagnostics) is the header's first line and a note.
        let (head, rest) = d.message.split_once('\n').unwrap_or((&d.message, ""));
        let diagnostic = match d.severity {
            Severity::Error => Diagnostic::error(),
            Severity::Warning | Severity::Omission => Diagnostic::warning(),
        }
        .with_message(head)
        .with_labels(vec![Label::primary(id, span)])
        .with_notes(if rest.trim().is_empty() { Vec::new() } else { vec![rest.trim_end().to_string()] });
        if term::emit_to_write_style(out, &config, &files, &diagnostic).is_err() {
            writeln!(out, "{d}")?;
        }
    }
    Ok(())
}

/// [`write_diagnostics`] into a string, without colour.
pub fn render(diagnostics: &[RibDiagnostic]) -> String {
    let mut out = term::termcolor::NoColor::new(Vec::new());
    // Writing to memory cannot fail.
    let _ = write_diagnostics(diagnostics, &mut out);
    String::from_utf8_lossy(&out.into_inner()).into_owned()
}

/// The bytes of the word at 1-based `line` and `column` (in characters) of `text`: up to the next
/// white space, at least one character. `None` when the location is not in the text.
fn span_at(text: &str, line: u32, column: u32) -> Option<std::ops::Range<usize>> {
    if line == 0 || column == 0 {
        return None;
    }
    let line_text = text.split_inclusive('\n').nth(line as usize - 1)?;
    let line_start = line_text.as_ptr() as usize - text.as_ptr() as usize;
    let (offset, _) = line_text.char_indices().nth(column as usize - 1)?;
    let word = &line_text[offset..];
    let len = word.find(char::is_whitespace).unwrap_or(word.len()).max(word.chars().next()?.len_utf8());
    Some(line_start + offset..line_start + offset + len)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rib::request::Location;
    use std::sync::Arc;

    #[test]
    fn diagnostics_show_their_line_with_the_request_underlined() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let file = dir.path().join("s.rib");
        std::fs::write(&file, "WorldBegin\n  Frobnicate 3\nWorldEnd\n").expect("written");
        let at = |line, column| Location { file: Arc::from(file.as_path()), line, column };
        let shown = render(&[
            RibDiagnostic::omission(&at(2, 3), "unknown request `Frobnicate` skipped"),
            RibDiagnostic::warning(&at(2, 3), "a shader's complaint\nerror[E0100]: undefined variable"),
        ]);
        let name = file.display().to_string();
        assert!(shown.starts_with("warning: unknown request `Frobnicate` skipped\n"), "{shown}");
        assert!(shown.contains(&format!("┌─ {name}:2:3")), "{shown}");
        assert!(shown.contains("2 │   Frobnicate 3\n  │   ^^^^^^^^^^\n"), "{shown}");
        assert!(shown.contains("= error[E0100]: undefined variable"), "{shown}");
        // Streams without a file, and places not in the file, stay one line each.
        let elsewhere = Location { file: Arc::from(Path::new("<default scene>")), line: 1, column: 1 };
        let shown = render(&[RibDiagnostic::warning(&elsewhere, "x"), RibDiagnostic::warning(&at(9, 1), "y")]);
        assert_eq!(shown, format!("<default scene>:1:1: warning: x\n{name}:9:1: warning: y\n"));
    }
}
