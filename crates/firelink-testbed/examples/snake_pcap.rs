//! Writes a pcap file of a short Snake session (seed 001's six 7-channel
//! nodes on the simulated bus), as the PC's port sees it: discovery, the
//! set-up of node 0's channels (wiper, analog switches, current limit,
//! encoder preload: quadlet reads and writes of Table 1), then a few
//! real-time cycles (the 23-quadlet block read and the 7-quadlet block
//! write of every node). Wireshark decodes it with
//! `tools/wireshark/firelink.lua`; `scripts/make-captures` runs this.
//!
//! ```sh
//! cargo run -p firelink-testbed --example snake_pcap -- snake.pcap 2
//! ```
//!
//! Arguments: the file (default `snake.pcap`) and the number of cycles
//! (default 2).

use std::io::BufWriter;

use firelink_control::config::presets;
use firelink_host::Port;
use firelink_host::snake::SnakeSystem;
use firelink_host::trace::PcapWriter;
use firelink_testbed::snake::{node_configs, sim_port};
use firelink_wire::snake::address::{GlobalRegister, SnakeRegister};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| "snake.pcap".into());
    let cycles: u32 = args.next().map_or(Ok(2), |n| n.parse())?;
    let config = presets::snake_seed001();
    let mut port = sim_port(node_configs(&config, 1)?, false, None)?;
    let file = BufWriter::new(std::fs::File::create(&path)?);
    port.add_link_filter(Box::new(PcapWriter::new(file)?))?;
    let mut system = SnakeSystem::open(port)?;
    system.read_register(0, SnakeRegister::Global(GlobalRegister::WatchdogPeriod))?;
    for ch in 1..=2 {
        system.set_digital_pot_wiper(0, ch, 512)?;
        system.set_motor_current(0, ch, 0x4000)?;
        system.set_encoder_preload(0, ch, 0x80_0000)?;
    }
    for _ in 0..cycles {
        system.latch_all_inputs();
        system.apply_all_outputs();
    }
    // The writer flushes when the port (and its filters) is dropped.
    drop(system);
    println!("{path}: Snake discovery, set-up of node 0 and {cycles} cycles");
    Ok(())
}
