//! Opening what a [`PortSpec`] names: the boards `sim` means for a robot
//! ([`sim_boards`]), a FireWire card ([`fw_port`]), and any port for the
//! programs that run no robot of their own (the CLI's bus tools, Python's
//! `Port`: [`open_bus_port`]). The robot programs (demo, service) match on
//! the spec themselves, since each kind of port gives a different port
//! type; they take their boards from here.
//!
//! This module opens sockets and device files (UDP, /dev/fw*); it reads no
//! clock.

use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, Profile};
use firelink_control::config::{IoConfig, presets};
use firelink_host::Port;
use firelink_host::udp::{UdpPort, WaitMode};

use crate::TestbedError;
use crate::port_spec::{PortKind, PortSpec};
use crate::rig;

/// How a port is opened beyond its string.
#[derive(Debug, Clone, Copy)]
pub struct PortOptions {
    /// How long one read waits for its answer (UDP, FireWire).
    pub timeout: Duration,
    /// How a UDP port's reads wait.
    pub udp_wait: WaitMode,
    /// FireWire: write the card's STATE_CLEAR at open to stop its
    /// cycle-start packets (as the dVRK's host does).
    pub stop_cycle_master: bool,
    /// `sim`'s firmware when the string names none.
    pub firmware: Profile,
}

impl Default for PortOptions {
    fn default() -> Self {
        PortOptions {
            timeout: rig::UDP_TIMEOUT,
            udp_wait: WaitMode::default(),
            stop_cycle_master: true,
            firmware: Profile::Rev8,
        }
    }
}

/// The QLA-family boards `spec`'s `sim` puts on the bus for the robot of
/// `config`: boards 0..N (N from `sim:N`, else the highest board ID the
/// configuration uses plus one), each with the plants its configuration
/// gives it, at `sim:N:FW`'s firmware or else `firmware`.
pub fn sim_boards(spec: &PortSpec, config: &IoConfig, firmware: Profile) -> Vec<BoardConfig> {
    rig::board_configs(
        config,
        spec.sim_firmware(firmware),
        spec.sim_board_count(config.board_slots()),
    )
}

/// FireWire card `card` through Linux /dev/fw*.
///
/// # Errors
/// The host library's: no such device, no permission, not Linux.
#[cfg(target_os = "linux")]
pub fn fw_port(
    card: u32,
    options: &PortOptions,
) -> Result<firelink_host::firewire::FirewirePort, TestbedError> {
    use firelink_host::firewire::{FirewirePort, FwOptions};
    // One time-out bounds a call and, in all, the waits of a servo cycle.
    Ok(FirewirePort::open(FwOptions {
        card,
        stop_cycle_master: options.stop_cycle_master,
        timeout: options.timeout,
        cycle_budget: options.timeout,
    })?)
}

/// A UDP port to `addr` as `options` say.
///
/// # Errors
/// The socket could not be opened.
pub fn udp_port(
    addr: std::net::SocketAddr,
    options: &PortOptions,
) -> Result<UdpPort, TestbedError> {
    let mut port = rig::udp_port_with(addr, options.udp_wait)?;
    port.set_timeout(options.timeout);
    Ok(port)
}

/// Open `spec` for `command`, a program that runs no robot of its own
/// (scan, read, write, monitor, Python's `Port`): `sim` is seed 000's dVRK
/// ([`sim_boards`] of `configs/dvrk-seed000.json`); `emulate`, whose
/// bridge would live only as long as one command, is refused (run
/// `firelink emulate` and use `udp:`).
///
/// # Errors
/// [`TestbedError::PortRefused`] for `emulate`; what opening the port
/// finds.
pub fn open_bus_port(
    command: &str,
    spec: &PortSpec,
    options: &PortOptions,
) -> Result<Box<dyn Port + Send>, TestbedError> {
    spec.refuse_unless(command, &[PortKind::Sim, PortKind::Udp, PortKind::Fw])?;
    Ok(match spec {
        PortSpec::Sim(_) => {
            let boards = sim_boards(spec, &presets::dvrk_seed000(), options.firmware);
            Box::new(rig::sim_port(boards, false)?.0)
        }
        PortSpec::Udp(addr) | PortSpec::UdpFw(addr) => {
            let force_bridge = matches!(spec, PortSpec::UdpFw(_));
            Box::new(firelink_host::eth::UdpNetPort::open(
                *addr,
                force_bridge,
                options.timeout,
                options.udp_wait,
            )?)
        }
        #[cfg(target_os = "linux")]
        PortSpec::Fw(card) => Box::new(fw_port(*card, options)?),
        _ => {
            return Err(spec
                .refused(command, "not available on this system".into())
                .into());
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_host::qla::scan::scan;

    /// `sim` is the dVRK's eight boards; `sim:N:FW` the first N at FW;
    /// `emulate` is refused naming the command.
    #[test]
    fn bus_tools_see_the_dvrk_boards() {
        let mut port = open_bus_port("t", &PortSpec::SIM, &PortOptions::default()).unwrap();
        let found = scan(&mut port).unwrap();
        assert_eq!(found.boards.len(), 8);
        let mut port =
            open_bus_port("t", &"sim:3:7".parse().unwrap(), &PortOptions::default()).unwrap();
        let found = scan(&mut port).unwrap();
        assert_eq!(found.boards.len(), 3);
        assert_eq!(found.boards[0].firmware, 7);
        let e = open_bus_port("firelink scan", &PortSpec::Emulate, &PortOptions::default())
            .err()
            .unwrap();
        assert_eq!(
            e.to_string(),
            "firelink scan: port emulate cannot be used: it takes sim, udp, fw"
        );
    }
}
