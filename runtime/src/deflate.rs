//! The payloads the ranks of a distributed render send each other once and keep (demand-loaded
//! objects, their BVH parts, textures): plain or deflated, a first byte saying which. Deflated
//! pays where the link is slower than inflating (between machines); between ranks of one machine,
//! which MPI joins through shared memory, copying the plain bytes costs less than deflating them
//! on the master and inflating them on a worker (`Master::set_deflate`). Deflating uses the
//! fastest level, since the master compresses while a worker waits; inflating is bounded, since
//! the bytes come from another process.

use std::borrow::Cow;
use std::io::{Read, Write};

/// The first byte of a plain payload.
const PLAIN: u8 = 0;
/// The first byte of a deflated payload.
const DEFLATED: u8 = 1;

/// `parts` one after the other, as a payload: deflated when `deflated` is set, else plain.
pub(crate) fn pack(parts: &[&[u8]], deflated: bool) -> Vec<u8> {
    if !deflated {
        let mut plain = Vec::with_capacity(1 + parts.iter().map(|p| p.len()).sum::<usize>());
        plain.push(PLAIN);
        for part in parts {
            plain.extend_from_slice(part);
        }
        return plain;
    }
    let mut deflated = flate2::write::DeflateEncoder::new(vec![DEFLATED], flate2::Compression::fast());
    for part in parts {
        // Writing to a vector cannot fail.
        let _ = deflated.write_all(part);
    }
    deflated.finish().unwrap_or_default()
}

/// The bytes of a payload [`pack`] wrote, when they are at most `limit`; else why not (an
/// unknown first byte, data that does not inflate, or too many bytes).
pub(crate) fn unpack_at_most(bytes: &[u8], limit: u64) -> Result<Cow<'_, [u8]>, String> {
    match bytes.split_first() {
        Some((&PLAIN, plain)) if plain.len() as u64 <= limit => Ok(Cow::Borrowed(plain)),
        Some((&PLAIN, _)) => Err(format!("is more than {} MiB", limit >> 20)),
        Some((&DEFLATED, deflated)) => inflate_at_most(deflated, limit).map(Cow::Owned),
        Some((kind, _)) => Err(format!("is of an unknown kind ({kind})")),
        None => Err("is empty".into()),
    }
}

/// What `bytes` inflate to, when they are deflated data of at most `limit` bytes; else why not.
fn inflate_at_most(bytes: &[u8], limit: u64) -> Result<Vec<u8>, String> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payloads_unpack_to_what_was_packed_plain_or_deflated() {
        let text: Vec<u8> = (0..5000u32).flat_map(|i| (i % 97).to_le_bytes()).collect();
        let parts: [&[u8]; 3] = [b"head", &text, b"tail"];
        let whole: Vec<u8> = parts.concat();
        let plain = pack(&parts, false);
        let deflated = pack(&parts, true);
        assert_eq!(plain.len(), whole.len() + 1);
        assert!(deflated.len() < whole.len() / 4, "{} of {}", deflated.len(), whole.len());
        for packed in [&plain, &deflated] {
            assert_eq!(unpack_at_most(packed, whole.len() as u64).as_deref(), Ok(&whole[..]));
            // One byte over the limit, either way: refused.
            assert!(unpack_at_most(packed, whole.len() as u64 - 1).is_err());
        }
        // Damaged payloads are errors: an unknown kind, nothing, deflated data cut short.
        let mut unknown = plain.clone();
        unknown[0] = 7;
        assert!(unpack_at_most(&unknown, u64::MAX).is_err());
        assert!(unpack_at_most(&[], u64::MAX).is_err());
        assert!(unpack_at_most(&deflated[..deflated.len() / 2], u64::MAX).is_err());
    }
}
