//! Deflate for what the ranks of a distributed render send each other once and keep (demand-loaded
//! objects and textures): the fastest level, since the master compresses while a worker waits, and
//! inflating bounded, since the bytes come from another process.

use std::io::{Read, Write};

/// `parts` one after the other, deflated.
pub(crate) fn deflate(parts: &[&[u8]]) -> Vec<u8> {
    let mut deflated = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::fast());
    for part in parts {
        // Writing to a vector cannot fail.
        let _ = deflated.write_all(part);
    }
    deflated.finish().unwrap_or_default()
}

/// What `bytes` inflate to, when they are deflated data of at most `limit` bytes; else why not.
pub(crate) fn inflate_at_most(bytes: &[u8], limit: u64) -> Result<Vec<u8>, String> {
    let mut plain = Vec::new();
    flate2::read::DeflateDecoder::new(bytes)
        .take(limit.saturating_add(1))
        .read_to_end(&mut plain)
        .map_err(|e| format!("cannot be inflated: {e}"))?;
    if plain.len() as u64 > limit {
        return Err(format!("inflates past {} MiB", limit >> 20));
    }
    Ok(plain)
}
