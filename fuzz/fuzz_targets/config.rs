//! Fuzz configuration loading: any text given as a saw-robot-io v6 file
//! either loads (and then saves and reloads to the same configuration) or
//! is rejected with errors that name the file; it never panics.
#![no_main]

use firelink_control::config::IoConfig;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match IoConfig::from_json_str(&text, "fuzz.json") {
        Ok(config) => {
            let saved = config.to_json_pretty();
            let again = IoConfig::from_json_str(&saved, "saved.json")
                .expect("a loaded configuration saves to one that loads");
            assert_eq!(again, config, "save and reload changed the configuration");
        }
        Err(errors) => {
            let message = errors.to_string();
            assert!(message.contains("fuzz.json"), "error without the file: {message}");
        }
    }
    // Unvalidated parsing is total too.
    let _ = IoConfig::parse_unvalidated(&text, "fuzz.json");
});
