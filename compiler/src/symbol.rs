//! Interned strings: identifiers, number spellings and string literal values.
//!
//! The keywords of the language are interned first, in the order of [`KEYWORDS`], so that
//! `Symbol(i)` for `i < KEYWORDS.len()` is keyword `i`. The lexer produces every word as an
//! identifier; the preprocessor treats them alike (a macro may share a keyword's name), and the parser
//! tells keywords apart by this numbering alone.

use rustc_hash::FxHashMap;

/// An interned string. Cheap to copy and compare.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Symbol(pub u32);

/// Reserved words, in the order the parser's keyword table expects.
pub const KEYWORDS: &[&str] = &[
    "float",
    "color",
    "point",
    "vector",
    "normal",
    "matrix",
    "string",
    "void",
    "uniform",
    "varying",
    "output",
    "extern",
    "if",
    "else",
    "while",
    "for",
    "break",
    "continue",
    "return",
    "illuminance",
    "illuminate",
    "solar",
    "gather",
    "surface",
    "light",
    "displacement",
    "volume",
    "imager",
    "pixel",
    "camera",
    "lightfield",
];

#[derive(Debug)]
pub struct Interner {
    map: FxHashMap<Box<str>, Symbol>,
    strings: Vec<Box<str>>,
}

impl Default for Interner {
    fn default() -> Self {
        Interner::new()
    }
}

impl Interner {
    pub fn new() -> Interner {
        let mut i = Interner { map: FxHashMap::default(), strings: Vec::new() };
        for k in KEYWORDS {
            i.intern(k);
        }
        i
    }

    pub fn intern(&mut self, s: &str) -> Symbol {
        if let Some(&sym) = self.map.get(s) {
            return sym;
        }
        let sym = Symbol(self.strings.len() as u32);
        let boxed: Box<str> = s.into();
        self.strings.push(boxed.clone());
        self.map.insert(boxed, sym);
        sym
    }

    pub fn get(&self, s: &str) -> Option<Symbol> {
        self.map.get(s).copied()
    }

    pub fn resolve(&self, sym: Symbol) -> &str {
        self.strings.get(sym.0 as usize).map(|s| &**s).unwrap_or("")
    }

    /// The keyword index of `sym`, if it is a keyword.
    pub fn keyword(sym: Symbol) -> Option<usize> {
        ((sym.0 as usize) < KEYWORDS.len()).then_some(sym.0 as usize)
    }
}
