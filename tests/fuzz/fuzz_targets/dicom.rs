//! Fuzzes the DICOM loader behind `input.dcm` files (dicom-rs parsing behind the length
//! check, pixel decoding of every codec, multi-frame placement, series assembly) and the
//! reorientation for display. Besides the seeds here, run it on the fetched public files:
//! `cargo +nightly fuzz run --fuzz-dir tests/fuzz dicom tests/fuzz/corpus/dicom
//! tests/fuzz/seeds/dicom target/datasets/dicom`.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::load("input.dcm", data);
});
