//! Fuzzes the volume loader behind `input.nrrd` files.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::load("input.nrrd", data);
});
