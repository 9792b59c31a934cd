//! The headers shader collections include by name (`filterwidth.h`, `noises.h`, `patterns.h`),
//! written for this library from their documented behaviour (`stdlib_shaders/include/`) and built
//! into the compiler, so that they are found on every machine. They come last on the include
//! path: a header of the same name in the shader's directory or an `-I` directory wins.

/// Name and text of each standard header.
pub const STANDARD_HEADERS: &[(&str, &str)] = &[
    ("filterwidth.h", include_str!("../../../../stdlib_shaders/include/filterwidth.h")),
    ("noises.h", include_str!("../../../../stdlib_shaders/include/noises.h")),
    ("patterns.h", include_str!("../../../../stdlib_shaders/include/patterns.h")),
];

/// The text of the standard header `name` (as written in `#include`, a leading `./` allowed).
pub fn standard_header(name: &str) -> Option<&'static str> {
    let name = name.strip_prefix("./").unwrap_or(name);
    STANDARD_HEADERS.iter().find(|(n, _)| *n == name).map(|(_, text)| *text)
}

/// How diagnostics name a standard header.
pub fn label(name: &str) -> String {
    format!("<built-in library>/include/{name}")
}
