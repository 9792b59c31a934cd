//! `--color`: whether diagnostics (the compiler's and the RIB reader's) are coloured, and the
//! output streams that follow the choice.

use codespan_reporting::term::termcolor::{ColorChoice, StandardStream};
use std::io::IsTerminal;
use std::sync::OnceLock;

/// `--color auto|always|never`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum When {
    /// On a terminal, unless `NO_COLOR` is set or `TERM` is `dumb`.
    #[default]
    Auto,
    Always,
    Never,
}

static CHOSEN: OnceLock<When> = OnceLock::new();

/// Records the command line's choice (the first call wins).
pub fn set(when: When) {
    let _ = CHOSEN.set(when);
}

/// What a stream that is (or is not) a terminal gets.
fn choice(is_terminal: bool) -> ColorChoice {
    match CHOSEN.get().copied().unwrap_or_default() {
        When::Always => ColorChoice::Always,
        When::Never => ColorChoice::Never,
        // termcolor's `Auto` looks at NO_COLOR and TERM, not at whether the stream is a terminal.
        When::Auto if is_terminal => ColorChoice::Auto,
        When::Auto => ColorChoice::Never,
    }
}

/// Standard error, coloured as chosen.
pub fn stderr() -> StandardStream {
    StandardStream::stderr(choice(std::io::stderr().is_terminal()))
}

/// Standard output, coloured as chosen.
pub fn stdout() -> StandardStream {
    StandardStream::stdout(choice(std::io::stdout().is_terminal()))
}
