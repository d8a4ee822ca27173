//! Fuzzes raw files with a JSON sidecar: the first line of the input is the sidecar, the rest
//! the samples.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let split = data.iter().position(|&b| b == b'\n').unwrap_or(data.len());
    common::input_file("input.raw.json", &data[..split]);
    common::load("input.raw", data.get(split + 1..).unwrap_or(&[]));
});
