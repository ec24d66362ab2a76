//! What the command line says to an operator: errors as sentences with
//! numbers as written, addresses it will not silently alias, port names it
//! resolves, idle boards explained (issue 28, item 9).

use crate::common;

use common::{firelink, ok};

fn stderr(args: &[&str]) -> (i32, String) {
    let out = firelink(args);
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn offsets_beyond_the_board_map_are_refused() {
    for (address, says) in [
        ("0x100000000", "beyond the board's address map"),
        ("0x10000", "beyond the board's address map"),
        ("0x1000000000000", "48-bit"),
        ("18446744073709551615", "48-bit"),
    ] {
        for args in [
            &["read", "--port", "sim:1", "--board", "0", address][..],
            &["write", "--port", "sim:1", "--board", "0", address, "1"],
        ] {
            let (code, err) = stderr(args);
            assert_eq!(code, 2, "{args:?}: {err}");
            assert!(err.contains(says), "{args:?}: {err}");
            assert!(err.contains(&format!("address {address}")) || err.contains("address 0x"));
        }
    }
    // A block that would run past the end of the map.
    let (code, err) = stderr(&["read", "--port", "sim:1", "--count", "2", "0xffff"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("run past the end"), "{err}");
    // Inside the map, as before.
    assert!(ok(&["read", "--port", "sim:1", "0x0"]).starts_with("0x0000: "));
}

#[test]
fn port_addresses_say_what_is_wrong() {
    for (port, says) in [
        ("udp:", "expected udp:HOST or udp:HOST:PORT"),
        (
            "udp:localhost:99999",
            "the UDP port must be a number from 1 to 65535",
        ),
        ("udp:local host", "expected udp:HOST"),
    ] {
        for args in [
            &["scan", "--port", port][..],
            &["demo", "--port", port],
            &["bench", "--transport", "udp", "--port", port],
        ] {
            let (code, err) = stderr(args);
            assert_eq!(code, 2, "{args:?}: {err}");
            assert!(err.contains(says), "{args:?}: {err}");
            assert!(err.contains(&format!("port {port:?}")), "{args:?}: {err}");
            assert!(!err.contains("(value 0)"), "{err}");
        }
    }
}

#[test]
fn idle_boards_are_explained_in_the_monitor() {
    let frame = ok(&["monitor", "--port", "sim:2", "--once", "3"]);
    assert!(frame.contains("supply off "), "{frame}");
    assert!(
        frame.contains("supply off: motor power is not enabled (normal for idle boards)"),
        "{frame}"
    );
    assert!(!frame.contains("supply BAD"), "{frame}");
}

#[test]
fn the_help_documents_the_exit_statuses() {
    let help = ok(&["--help"]);
    assert!(help.contains("Exit status: 0 done"), "{help}");
    assert!(
        help.contains("3 the run finished but failed its check"),
        "{help}"
    );
}
