//! The TOML scene-file parser on arbitrary text: it must return a scene or a
//! `SceneError`, never panic, and an error must render as a message.

#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(e) = raypack::scene::file::parse(Path::new("fuzz.toml"), text) {
        let _ = e.to_string();
    }
});
