//! Writes the shipped configurations to `configs/` at the repository root
//! (or to the directory given as the first argument).
//!
//! ```sh
//! cargo run -p firelink-control --example write_configs
//! ```

use firelink_control::config::presets;
use std::path::PathBuf;

fn main() -> std::io::Result<()> {
    let dir = std::env::args_os().nth(1).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs"),
        PathBuf::from,
    );
    std::fs::create_dir_all(&dir)?;
    for (name, config) in presets::shipped() {
        if let Err(e) = config.validate(name) {
            eprintln!("{e}");
            std::process::exit(1);
        }
        let path = dir.join(name);
        std::fs::write(&path, config.to_json_pretty())?;
        println!(
            "{}: {} robots, {} actuators, boards {:?}",
            path.display(),
            config.robots.len(),
            config.actuator_count(),
            config.board_set()
        );
    }
    Ok(())
}
