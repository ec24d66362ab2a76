//! The port the tool talks through: plain `sim` is the configuration's
//! own Snake nodes on an in-process simulated bus (their state lasts as
//! long as the port); `udp:` and `fw` are opened as every bus tool opens
//! them.

use firelink_control::config::IoConfig;
use firelink_host::Port;

use crate::TestbedError;
use crate::port_spec::PortSpec;
use crate::ports::{PortOptions, open_bus_port};
use crate::snake::{node_configs, sim_port};

/// Open `spec` for the Snake tool, simulating `config`'s nodes on `sim`.
///
/// # Errors
/// `config` maps no Snake nodes; the port cannot be opened or is not
/// one the tool takes.
pub fn open_tool_port(
    spec: &PortSpec,
    config: &IoConfig,
    options: &PortOptions,
) -> Result<Box<dyn Port>, TestbedError> {
    match spec {
        PortSpec::Sim(_) => Ok(Box::new(sim_port(node_configs(config, 1)?, false, None)?)),
        other => Ok(open_bus_port("firelink snake-tool", other, options)?),
    }
}
