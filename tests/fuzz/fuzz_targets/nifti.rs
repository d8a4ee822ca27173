//! Fuzzes the volume loader behind `input.nii` files.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    // Plain and gzip-compressed inputs go through the same file name; the reader sniffs gzip.
    common::load("input.nii", data);
});
