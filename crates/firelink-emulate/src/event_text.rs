//! What the servers report, as the one line a front end prints for each
//! event (`firelink emulate` shows them as they happen).

use core::fmt;

use crate::Event;
use crate::qla::eth_serve::EthEvent;

/// "12.3 ms behind real time".
fn lagging(out: &mut fmt::Formatter<'_>, behind: core::time::Duration) -> fmt::Result {
    write!(
        out,
        "emulation is {:.1} ms behind real time (machine busy)",
        behind.as_secs_f64() * 1e3
    )
}

impl fmt::Display for Event {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Event::Listening { addr, broadcast } => write!(
                out,
                "listening on udp {addr}{}",
                if *broadcast {
                    " (and the loopback broadcast address)"
                } else {
                    ""
                }
            ),
            Event::HostSeen(from) => write!(out, "host {from} connected"),
            Event::BusReset(g) => write!(out, "bus reset: generation {g}"),
            Event::Lagging(d) => lagging(out, *d),
            Event::Stopped(s) => write!(out, "stopped: {s}"),
        }
    }
}

impl fmt::Display for EthEvent {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EthEvent::Listening {
                boards,
                broadcast,
                multicast,
            } => {
                let list: Vec<String> = boards.iter().map(|(id, a)| format!("{id}={a}")).collect();
                write!(out, "listening on udp {}", list.join(" "))?;
                if let Some(b) = broadcast {
                    write!(out, ", broadcast {b}")?;
                }
                if let Some(m) = multicast {
                    write!(out, ", multicast {m}")?;
                }
                Ok(())
            }
            EthEvent::HostSeen(from) => write!(out, "host {from} connected"),
            EthEvent::Lagging(d) => lagging(out, *d),
            EthEvent::Stopped(s) => write!(out, "stopped: {s}"),
        }
    }
}

#[cfg(target_os = "linux")]
impl fmt::Display for crate::fw_cdev::ServeEvent {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        use crate::fw_cdev::ServeEvent;
        match self {
            ServeEvent::Listening(p) => {
                write!(out, "firewire-cdev twin listening on {}", p.display())
            }
            ServeEvent::Opened { device, connection } => {
                write!(out, "/dev/fw{device} opened (connection {connection})")
            }
            ServeEvent::BusReset(g) => write!(out, "bus reset: generation {g}"),
            ServeEvent::Stopped(s) => write!(out, "stopped: {s}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_read_as_one_line() {
        let addr = "127.0.0.1:1394".parse().unwrap();
        let e = Event::Listening {
            addr,
            broadcast: true,
        };
        assert_eq!(
            e.to_string(),
            "listening on udp 127.0.0.1:1394 (and the loopback broadcast address)"
        );
        let boards = vec![
            (0, "127.0.0.100:1394".parse().unwrap()),
            (1, "127.0.0.101:1394".parse().unwrap()),
        ];
        let e = EthEvent::Listening {
            boards,
            broadcast: None,
            multicast: None,
        };
        assert_eq!(
            e.to_string(),
            "listening on udp 0=127.0.0.100:1394 1=127.0.0.101:1394"
        );
        let e = Event::Lagging(core::time::Duration::from_micros(12_340));
        assert_eq!(
            e.to_string(),
            "emulation is 12.3 ms behind real time (machine busy)"
        );
    }
}
