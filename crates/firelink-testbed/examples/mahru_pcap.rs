//! Writes a pcap file of a short MAHRU session (seed 002's humanoid on the
//! simulated bus), as the computer's port sees it: bring-up (IDREQUEST,
//! IDCHECK, PARAMETER, SETBIAS, READY, START), a few control periods
//! (QREAD, FTREAD, QWRITE) and STOP. Wireshark decodes it with
//! `tools/wireshark/firelink.lua`; `scripts/make-captures` runs this.
//!
//! ```sh
//! cargo run -p firelink-testbed --example mahru_pcap -- mahru.pcap 3
//! ```
//!
//! Arguments: the file (default `mahru.pcap`) and the number of control
//! periods after bring-up (default 3).

use std::io::BufWriter;

use firelink_host::Port;
use firelink_host::mahru::MotionController;
use firelink_host::trace::PcapWriter;
use firelink_testbed::mahru::MahruConfig;
use firelink_testbed::mahru::main_loop::MainLoop;
use firelink_testbed::mahru::rig::robot_port;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| "mahru.pcap".into());
    let periods: u32 = args.next().map_or(Ok(3), |n| n.parse())?;
    let config = MahruConfig::seed002();
    let (mut port, _, _) = robot_port(&config)?;
    let file = BufWriter::new(std::fs::File::create(&path)?);
    port.add_link_filter(Box::new(PcapWriter::new(file)?))?;
    let mut controller = MotionController::new(port, config.layout()?)?;
    controller.bring_up()?;
    let mut main = MainLoop::new(&config, config.period());
    for _ in 0..periods {
        main.period_once(&mut controller, |_| {})?;
    }
    controller.stop()?;
    // The writer flushes when the port (and its filters) is dropped.
    drop(controller);
    println!("{path}: MAHRU bring-up, {periods} periods and STOP");
    Ok(())
}
