//! Fuzzes the transfer-function importers (ParaView JSON, Inviwo .itf, Slicer presets.xml,
//! caustica JSON): the first byte picks the file name, the rest is the content. Anything
//! accepted must validate.
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((&kind, content)) = data.split_first() else { return };
    let name = ["tf.json", "tf.itf", "presets.xml"][kind as usize % 3];
    let path = common::input_file(name, content);
    if let Ok(imported) = caustica::transfer::load_any(&path) {
        imported.tf.validate().expect("imported transfer functions validate");
        if let Some([lo, hi]) = imported.domain {
            assert!(lo.is_finite() && hi.is_finite() && hi > lo);
        }
    }
});
