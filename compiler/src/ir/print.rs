//! The IR's text form (filled in below).
