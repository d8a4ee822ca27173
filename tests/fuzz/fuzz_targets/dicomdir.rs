//! Fuzzes DICOMDIR reading: the directory records and the file paths they name (which must
//! stay inside the DICOMDIR's folder), then the series found.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::load("DICOMDIR", data);
});
