//! A page that can enable motor power: requests without the token or from
//! another origin are refused and change nothing; the right ones work.
//! Raw HTTP over loopback, against the console in process on the simulated
//! bus.

use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use firelink_testbed::demo::DemoPort;
use firelink_web::{WebOptions, serve, start};

/// Send one request, return (status, body).
async fn request(addr: std::net::SocketAddr, text: String) -> (u16, String) {
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(text.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    // Upgrades keep the connection open: read what arrives first.
    let _ = tokio::time::timeout(Duration::from_secs(20), async {
        let mut buf = [0u8; 4096];
        loop {
            match s.read(&mut buf).await {
                Ok(0) | Err(_) => break,
                Ok(n) => {
                    out.extend_from_slice(&buf[..n]);
                    if out.windows(4).any(|w| w == b"\r\n\r\n") && text.contains("Upgrade") {
                        break;
                    }
                }
            }
        }
    })
    .await;
    let reply = String::from_utf8_lossy(&out).to_string();
    let status = reply
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = reply.split("\r\n\r\n").nth(1).unwrap_or("").to_string();
    (status, body)
}

fn post(path: &str, origin: Option<&str>, body: &str) -> String {
    let origin = origin.map_or(String::new(), |o| format!("Origin: {o}\r\n"));
    format!(
        "POST {path} HTTP/1.1\r\nHost: x\r\n{origin}Content-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
}

fn get(path: &str, extra: &str) -> String {
    format!("GET {path} HTTP/1.1\r\nHost: x\r\n{extra}Connection: close\r\n\r\n")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_the_token_and_this_origin_can_change_the_robot() {
    let options = WebOptions {
        port: DemoPort::Sim,
        config: None,
        rate_hz: 500.0,
        watchdog: firelink_host::WatchdogSetting::default(),
        listen: "127.0.0.1:0".parse().unwrap(),
    };
    let (running, listener) = start(&options).await.unwrap();
    let addr = running.addr;
    let token = running.url.split("token=").nth(1).unwrap().to_string();
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let server = tokio::spawn(async move {
        serve(&running, listener, async {
            let _ = stop_rx.await;
        })
        .await
        .unwrap();
        running
    });
    let own = format!("http://{addr}");
    let configure = r#"{"action":"configure"}"#;
    let with_token = format!("/api/command?token={token}");

    // Refused: another site, no Origin, no token, a wrong token.
    for (path, origin) in [
        (with_token.as_str(), Some("http://evil.example")),
        (with_token.as_str(), Some("null")),
        (with_token.as_str(), None),
        ("/api/command", Some(own.as_str())),
        ("/api/command?token=0000", Some(own.as_str())),
    ] {
        let (status, body) = request(addr, post(path, origin, configure)).await;
        assert_eq!(status, 403, "{path} {origin:?}: {body}");
    }
    // A WebSocket from another origin or without the token is refused too.
    let upgrade = |origin: &str, token: &str| {
        get(
            &format!("/ws?token={token}"),
            &format!(
                "Origin: {origin}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
            ),
        )
    };
    assert_eq!(
        request(addr, upgrade("http://evil.example", &token))
            .await
            .0,
        403
    );
    assert_eq!(request(addr, upgrade(&own, "nope")).await.0, 403);
    // Reads of recorded data need the token.
    assert_eq!(request(addr, get("/api/csv", "")).await.0, 403);

    // The right ones work.
    assert_eq!(request(addr, upgrade(&own, &token)).await.0, 101);
    let (status, body) = request(addr, post(&with_token, Some(&own), configure)).await;
    assert_eq!(status, 200, "{body}");
    let (status, body) = request(addr, post(&with_token, Some(&own), r#"{"action":"fly"}"#)).await;
    assert_eq!(status, 400, "{body}");
    assert!(body.contains("unknown action"), "{body}");
    let (status, body) = request(addr, get(&format!("/api/csv?token={token}&seconds=1"), "")).await;
    assert_eq!(status, 200);
    assert!(body.starts_with("t_s,MTML"), "{body}");

    stop_tx.send(()).unwrap();
    let running = server.await.unwrap();
    // Exactly one command reached the robot: the refused ones never did.
    assert_eq!(running.commands_accepted(), 1);
    running.stop();
}
