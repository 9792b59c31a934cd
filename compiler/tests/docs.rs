//! The generated parts of `docs/language.md` (the globals and built-ins tables) match the compiler's
//! tables. `RTSL_BLESS=1` rewrites them.

use rtsl_compiler::builtins::{self, Builtin};
use rtsl_compiler::globals::{Access, GLOBALS};
use rtsl_compiler::interface::ShaderKind;
use std::path::Path;

fn globals_table() -> String {
    let mut s =
        String::from("Access: `r` read, `rw` read and write, blank: not available.\n\n| global | type | storage |");
    for k in ShaderKind::ALL {
        s.push_str(&format!(" {} |", k.name()));
    }
    s.push_str(" meaning |\n|---|---|---|");
    for _ in ShaderKind::ALL {
        s.push_str("---|");
    }
    s.push_str("---|\n");
    for g in GLOBALS {
        s.push_str(&format!("| `{}` | {} | {} |", g.name, g.ty, if g.varying { "varying" } else { "uniform" }));
        for k in ShaderKind::ALL {
            let a = match g.access(k) {
                Access::None => "",
                Access::Read => "r",
                Access::Write => "rw",
            };
            s.push_str(&format!(" {a} |"));
        }
        s.push_str(&format!(" {} |\n", g.doc));
    }
    s
}

fn builtins_table() -> String {
    let mut s = String::from(
        "Signatures are written `result name(arguments)`; `\"name\", value...` is a parameter list.\n\
         Runs: `inline` (expanded in the shader's code), `lane` (a vectorised helper per chunk of lanes),\n\
         `host` (a call into the renderer per batch).\n\n| built-in | signatures | runs | meaning |\n|---|---|---|---|\n",
    );
    let mut all: Vec<Builtin> = Builtin::ALL.to_vec();
    all.sort_by_key(|b| b.name().to_lowercase());
    for b in all {
        let mut sigs: Vec<String> = Vec::new();
        for sig in builtins::signatures(b) {
            let d = builtins::describe(b, sig);
            if !sigs.contains(&d) {
                sigs.push(d);
            }
        }
        let runs = match b.exec() {
            builtins::Exec::Inline => "inline",
            builtins::Exec::Lane => "lane",
            builtins::Exec::Host => "host",
        };
        s.push_str(&format!(
            "| `{}` | {} | {runs} | {} |\n",
            b.name(),
            sigs.iter().map(|x| format!("`{x}`")).collect::<Vec<_>>().join("<br>"),
            b.doc()
        ));
    }
    s
}

fn replace_section(doc: &str, name: &str, body: &str) -> String {
    let start = format!("<!-- generated:{name} -->\n");
    let end = format!("<!-- end:{name} -->");
    let (a, rest) = doc.split_once(&start).expect("start marker");
    let (_, b) = rest.split_once(&end).expect("end marker");
    format!("{a}{start}{body}{end}{b}")
}

#[test]
fn language_reference_tables_are_current() {
    let path = Path::new("..").join("docs").join("language.md");
    let doc = std::fs::read_to_string(&path).expect("docs/language.md");
    let want = replace_section(&replace_section(&doc, "globals", &globals_table()), "builtins", &builtins_table());
    if std::env::var_os("RTSL_BLESS").is_some() {
        std::fs::write(&path, &want).expect("writable");
        return;
    }
    assert!(
        doc == want,
        "docs/language.md tables are stale: run `RTSL_BLESS=1 cargo test -p rtsl-compiler --test docs`"
    );
}
