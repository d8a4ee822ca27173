//! Fuzzes the volume loader behind `input.mha` files.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::load("input.mha", data);
});
