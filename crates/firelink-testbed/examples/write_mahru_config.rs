//! Writes seed 002's MAHRU configuration to `configs/mahru-seed002.json`
//! at the repository root (or to the file given as the first argument).
//!
//! ```sh
//! cargo run -p firelink-testbed --example write_mahru_config
//! ```

use std::path::PathBuf;

use firelink_testbed::mahru::MahruConfig;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args_os().nth(1).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs/mahru-seed002.json"),
        PathBuf::from,
    );
    let config = MahruConfig::seed002();
    config.validate()?;
    let mut text = serde_json::to_string_pretty(&config)?;
    text.push('\n');
    std::fs::write(&path, text)?;
    println!("{}: {} modules", path.display(), config.modules().count());
    Ok(())
}
