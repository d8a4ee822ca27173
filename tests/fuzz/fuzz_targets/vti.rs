//! Fuzzes the volume loader behind `input.vti` files.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::load("input.vti", data);
});
