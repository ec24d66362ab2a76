//! A page that can switch motor power on: requests without the token (in
//! the header or the cookie, never the URL) or from another origin are
//! refused and change nothing; the right ones work, and a command is
//! answered with its outcome (409 with the reason when the robot's state
//! refuses it). Raw HTTP over loopback, against the console in process on
//! the simulated bus. Nothing here is timed: waits are bounded only so
//! that a broken build fails instead of hanging.

use std::net::SocketAddr;
use std::time::Duration;

use serde_json::Value;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use firelink_testbed::port_spec::PortSpec;
use firelink_testbed::service::LoopExit;
use firelink_web::server::cookie_name;
use firelink_web::{Running, WebOptions, serve, start};

/// Bounded only so that a broken build fails instead of hanging.
const HANG: Duration = Duration::from_secs(300);

/// One answer: status, headers (lower-case names) and body.
#[derive(Debug)]
struct Reply {
    status: u16,
    headers: Vec<(String, String)>,
    body: String,
}

impl Reply {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    fn json(&self) -> Value {
        serde_json::from_str(&self.body).unwrap_or_else(|e| panic!("{e}: {}", self.body))
    }
}

/// Send one request, return the reply (for an upgrade: its head).
async fn request(addr: SocketAddr, text: &str) -> Reply {
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(text.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    let _ = tokio::time::timeout(HANG, async {
        let mut buf = [0u8; 8192];
        loop {
            match s.read(&mut buf).await {
                Ok(0) | Err(_) => break,
                Ok(n) => {
                    out.extend_from_slice(&buf[..n]);
                    // Upgrades keep the connection open: the head is enough.
                    if out.windows(4).any(|w| w == b"\r\n\r\n") && text.contains("Upgrade") {
                        break;
                    }
                }
            }
        }
    })
    .await;
    let reply = String::from_utf8_lossy(&out).to_string();
    let (head, body) = reply.split_once("\r\n\r\n").unwrap_or((&reply, ""));
    let mut lines = head.lines();
    let status = lines
        .next()
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(n, v)| (n.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    Reply {
        status,
        headers,
        body: body.to_string(),
    }
}

/// A console in process on the simulated bus.
struct Console {
    addr: SocketAddr,
    token: String,
    stop: tokio::sync::oneshot::Sender<()>,
    server: tokio::task::JoinHandle<Running>,
}

impl Console {
    async fn start(allow_origins: Vec<String>) -> Console {
        let options = WebOptions {
            port: PortSpec::SIM,
            config: None,
            rate_hz: 1000.0,
            watchdog: firelink_host::WatchdogSetting::default(),
            listen: "127.0.0.1:0".parse().unwrap(),
            allow_origins,
        };
        let (running, listener) = start(&options).await.unwrap();
        let addr = running.addr;
        let token = running.token().to_string();
        assert_eq!(running.url, format!("http://{addr}/?token={token}"));
        let (stop, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let server = tokio::spawn(async move {
            serve(&running, listener, async {
                let _ = stop_rx.await;
            })
            .await
            .unwrap();
            running
        });
        Console {
            addr,
            token,
            stop,
            server,
        }
    }

    fn own(&self) -> String {
        format!("http://{}", self.addr)
    }

    fn host(&self) -> String {
        self.addr.to_string()
    }

    fn token_header(&self) -> String {
        format!("X-Firelink-Token: {}\r\n", self.token)
    }

    fn cookie(&self) -> String {
        format!(
            "Cookie: other=1; {}={}\r\n",
            cookie_name(self.addr.port()),
            self.token
        )
    }

    /// A command with the token header and this console's own Origin.
    async fn command(&self, body: &str) -> Reply {
        let extra = format!("{}Origin: {}\r\n", self.token_header(), self.own());
        request(self.addr, &post(&self.host(), "/api/command", &extra, body)).await
    }

    async fn state(&self) -> Value {
        let r = request(
            self.addr,
            &get(&self.host(), "/api/state", &self.token_header()),
        )
        .await;
        assert_eq!(r.status, 200, "{}", r.body);
        r.json()
    }

    /// Stop the server and the robot; what the power-down found.
    async fn stop(self) -> (u64, LoopExit) {
        self.stop.send(()).unwrap();
        let running = self.server.await.unwrap();
        let accepted = running.commands_accepted();
        (accepted, running.stop())
    }
}

fn post(host: &str, path: &str, extra: &str, body: &str) -> String {
    format!(
        "POST {path} HTTP/1.1\r\nHost: {host}\r\n{extra}Content-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
}

fn get(host: &str, path: &str, extra: &str) -> String {
    format!("GET {path} HTTP/1.1\r\nHost: {host}\r\n{extra}Connection: close\r\n\r\n")
}

fn upgrade(host: &str, path: &str, extra: &str) -> String {
    get(
        host,
        path,
        &format!(
            "{extra}Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
        ),
    )
}

const HARMLESS: &str = r#"{"action":"amplifiers","on":false}"#;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn everything_that_reveals_or_changes_state_needs_the_token_never_in_the_url() {
    let c = Console::start(Vec::new()).await;
    let (addr, host, own) = (c.addr, c.host(), c.own());
    let origin = format!("Origin: {own}\r\n");
    let reads = [
        "/api/state",
        "/api/info",
        "/api/csv?seconds=1",
        "/api/fig11.png",
        "/api/command/1",
    ];
    let wrong = [
        String::new(),
        "X-Firelink-Token: 0000\r\n".to_string(),
        format!("X-Firelink-Token: {}0\r\n", c.token),
        format!("Cookie: {}=0000\r\n", cookie_name(addr.port())),
        // The cookie of a console on another port.
        format!("Cookie: {}={}\r\n", cookie_name(addr.port() ^ 1), c.token),
    ];
    for path in reads {
        for extra in &wrong {
            let r = request(addr, &get(&host, path, extra)).await;
            assert_eq!(r.status, 403, "{path} {extra:?}: {}", r.body);
        }
        // The token in the URL is refused even where it is right.
        let sep = if path.contains('?') { '&' } else { '?' };
        let in_url = format!("{path}{sep}token={}", c.token);
        let r = request(addr, &get(&host, &in_url, "")).await;
        assert_eq!(r.status, 403, "{in_url}");
        assert!(r.body.contains("never in the URL"), "{}", r.body);
        // ... and with it in the header too: a URL must not carry it.
        let r = request(addr, &get(&host, &in_url, &c.token_header())).await;
        assert_eq!(r.status, 403, "{in_url}");
    }
    for extra in &wrong {
        let with_origin = format!("{extra}{origin}");
        let r = request(addr, &post(&host, "/api/command", &with_origin, HARMLESS)).await;
        assert_eq!(r.status, 403, "command {extra:?}: {}", r.body);
        let r = request(addr, &upgrade(&host, "/ws", &with_origin)).await;
        assert_eq!(r.status, 403, "ws {extra:?}");
    }
    let in_url = format!("/api/command?token={}", c.token);
    let r = request(addr, &post(&host, &in_url, &origin, HARMLESS)).await;
    assert_eq!(r.status, 403);
    let in_url = format!("/ws?token={}", c.token);
    assert_eq!(
        request(addr, &upgrade(&host, &in_url, &origin))
            .await
            .status,
        403
    );

    // The header or the cookie work, for reads, commands and the stream.
    for extra in [c.token_header(), c.cookie()] {
        for path in ["/api/state", "/api/info", "/api/csv?seconds=1"] {
            let r = request(addr, &get(&host, path, &extra)).await;
            assert_eq!(r.status, 200, "{path} {extra:?}: {}", r.body);
        }
        let with_origin = format!("{extra}{origin}");
        let r = request(addr, &post(&host, "/api/command", &with_origin, HARMLESS)).await;
        assert_eq!(r.status, 200, "{}", r.body);
        let r = request(addr, &upgrade(&host, "/ws", &with_origin)).await;
        assert_eq!(r.status, 101);
    }
    let r = request(addr, &get(&host, "/api/info", &c.cookie())).await;
    assert_eq!(r.json()["joints"].as_array().map(Vec::len), Some(28));
    let r = request(addr, &get(&host, "/api/csv?seconds=1", &c.token_header())).await;
    assert!(r.body.starts_with("t_s,MTML"), "{}", r.body);
    // The static page and its assets reveal nothing and need nothing.
    for path in ["/", "/app.js", "/app.css"] {
        assert_eq!(
            request(addr, &get(&host, path, "")).await.status,
            200,
            "{path}"
        );
    }

    let (accepted, exit) = c.stop().await;
    // Only the two right commands reached the robot.
    assert_eq!(accepted, 2);
    assert!(exit.is_clean(), "{exit}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_printed_url_sets_the_cookie_and_redirects_to_a_url_without_the_token() {
    let c = Console::start(Vec::new()).await;
    let (addr, host) = (c.addr, c.host());
    let r = request(addr, &get(&host, &format!("/?token={}", c.token), "")).await;
    assert_eq!(r.status, 303, "{}", r.body);
    assert_eq!(r.header("location"), Some("/"));
    let cookie = r.header("set-cookie").unwrap();
    let mut parts = cookie.split(';').map(str::trim);
    assert_eq!(
        parts.next(),
        Some(format!("{}={}", cookie_name(addr.port()), c.token).as_str())
    );
    let attributes: Vec<&str> = parts.collect();
    for a in ["HttpOnly", "SameSite=Strict", "Path=/"] {
        assert!(attributes.contains(&a), "{cookie}: no {a}");
    }
    // The cookie as the browser sends it back works.
    let back = format!("Cookie: {}\r\n", cookie.split(';').next().unwrap());
    assert_eq!(
        request(addr, &get(&host, "/api/state", &back)).await.status,
        200
    );
    // A wrong token sets nothing.
    let r = request(addr, &get(&host, "/?token=0000", "")).await;
    assert_eq!(r.status, 403);
    assert_eq!(r.header("set-cookie"), None);
    // The page never lets another site frame it.
    let r = request(addr, &get(&host, "/", "")).await;
    assert_eq!(r.status, 200);
    assert_eq!(r.header("x-frame-options"), Some("DENY"));
    c.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_this_consoles_origins_can_change_the_robot() {
    let c = Console::start(vec!["http://robot.lab:8080".into()]).await;
    let addr = c.addr;
    let port = addr.port();
    let send = |host: String, origin: Option<String>| {
        let extra = format!(
            "{}{}",
            c.token_header(),
            origin.map_or(String::new(), |o| format!("Origin: {o}\r\n"))
        );
        async move { request(addr, &post(&host, "/api/command", &extra, HARMLESS)).await }
    };
    // Accepted: the address reached, loopback names (on loopback), and the
    // origin given with --allow-origin.
    for (host, origin) in [
        (
            format!("127.0.0.1:{port}"),
            format!("http://127.0.0.1:{port}"),
        ),
        (
            format!("localhost:{port}"),
            format!("http://localhost:{port}"),
        ),
        (
            format!("LOCALHOST:{port}"),
            format!("http://localhost:{port}"),
        ),
        (format!("[::1]:{port}"), format!("http://[::1]:{port}")),
        // (A URL with 0.0.0.0 reaches this machine over loopback.)
        (format!("0.0.0.0:{port}"), format!("http://0.0.0.0:{port}")),
        ("robot.lab:8080".into(), "http://robot.lab:8080".into()),
        // (Any Host: the allowed origin is the operator's word.)
        (format!("127.0.0.1:{port}"), "http://robot.lab:8080".into()),
    ] {
        let r = send(host.clone(), Some(origin.clone())).await;
        assert_eq!(r.status, 200, "{host} {origin}: {}", r.body);
    }
    // Refused: another site; a name that resolves here (DNS rebinding);
    // an address this loopback listener was not reached at (as a browser
    // on another machine would send if it could reach it); another port;
    // https; a sandboxed page; none.
    for (host, origin) in [
        (
            format!("127.0.0.1:{port}"),
            Some("http://evil.example".to_string()),
        ),
        (
            format!("evil.example:{port}"),
            Some(format!("http://evil.example:{port}")),
        ),
        (
            format!("192.168.1.20:{port}"),
            Some(format!("http://192.168.1.20:{port}")),
        ),
        (
            format!("127.0.0.1:{port}"),
            Some(format!("http://127.0.0.1:{}", port ^ 1)),
        ),
        (
            format!("127.0.0.1:{port}"),
            Some(format!("https://127.0.0.1:{port}")),
        ),
        (
            "robot.lab:8081".into(),
            Some("http://robot.lab:8081".into()),
        ),
        (format!("127.0.0.1:{port}"), Some("null".into())),
        (format!("127.0.0.1:{port}"), None),
    ] {
        let r = send(host.clone(), origin.clone()).await;
        assert_eq!(r.status, 403, "{host} {origin:?}: {}", r.body);
    }
    let (accepted, _) = c.stop().await;
    assert_eq!(accepted, 7);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn commands_are_answered_with_their_outcome_and_refusals_are_409() {
    let c = Console::start(Vec::new()).await;
    let refused = |r: &Reply, why: &str| {
        assert_eq!(r.status, 409, "{}", r.body);
        let j = r.json();
        assert_eq!(j["result"], "refused", "{}", r.body);
        assert!(
            j["detail"].as_str().is_some_and(|d| d.contains(why)),
            "{}: expected {why:?}",
            r.body
        );
    };
    let ok = |r: &Reply| {
        assert_eq!(r.status, 200, "{}", r.body);
        assert_eq!(r.json()["result"], "ok", "{}", r.body);
        r.json()["detail"].as_str().unwrap_or("").to_string()
    };

    // Malformed: 400, nothing queued.
    for body in [
        "not json",
        r#"{"action":"fly"}"#,
        r#"{"action":"amplifiers"}"#,
        r#"{"action":"watchdog","watchdog_ms":0.001}"#,
        r#"{"action":"inject","fault":"none"}"#,
    ] {
        let r = c.command(body).await;
        assert_eq!(r.status, 400, "{body}: {}", r.body);
        assert_eq!(r.json()["result"], "malformed");
    }

    // Unconfigured: nothing may be switched on.
    let r = c.command(r#"{"action":"amplifiers","on":true}"#).await;
    refused(&r, "unconfigured");
    let id = r.json()["id"].as_u64().unwrap();
    refused(
        &c.command(r#"{"action":"relay","on":true}"#).await,
        "unconfigured",
    );
    refused(&c.command(r#"{"action":"power_on"}"#).await, "unconfigured");
    let state = c.state().await;
    assert!(
        state["axes"]
            .as_array()
            .unwrap()
            .iter()
            .all(|a| a["amp"] == false)
    );
    // The outcome can be asked for again by its id.
    let again = request(
        c.addr,
        &get(&c.host(), &format!("/api/command/{id}"), &c.token_header()),
    )
    .await;
    refused(&again, "unconfigured");
    let unknown = request(
        c.addr,
        &get(&c.host(), "/api/command/999999", &c.token_header()),
    )
    .await;
    assert_eq!(unknown.status, 404);

    // Configure says what it found.
    assert_eq!(
        ok(&c.command(r#"{"action":"configure"}"#).await),
        "boards found powered off"
    );
    refused(
        &c.command(r#"{"action":"configure"}"#).await,
        "cannot configure from state configured",
    );
    refused(
        &c.command(r#"{"action":"amplifiers","on":true}"#).await,
        "motor power",
    );

    // Powered, amplifiers off, then on: only the joints' 28 axes of 32.
    ok(&c.command(r#"{"action":"power_on"}"#).await);
    ok(&c.command(r#"{"action":"amplifiers","on":false}"#).await);
    let state = c.state().await;
    assert_eq!(state["state"], "configured");
    assert!(
        state["boards"]
            .as_array()
            .unwrap()
            .iter()
            .all(|b| b["power"] == true)
    );
    assert!(
        state["axes"]
            .as_array()
            .unwrap()
            .iter()
            .all(|a| a["amp"] == false)
    );
    let detail = ok(&c.command(r#"{"action":"amplifiers","on":true}"#).await);
    assert!(detail.contains("the other axes stay off"), "{detail}");
    let state = c.state().await;
    let on: Vec<(u64, u64)> = state["axes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["amp"] == true)
        .map(|a| (a["board"].as_u64().unwrap(), a["axis"].as_u64().unwrap()))
        .collect();
    let config = firelink_control::config::presets::dvrk_seed000();
    let mut used: Vec<(u64, u64)> = config
        .joints()
        .map(|j| {
            (
                u64::from(j.actuator.board_id),
                u64::from(j.actuator.axis_id),
            )
        })
        .collect();
    used.sort_unstable();
    assert_eq!(state["axes"].as_array().unwrap().len(), 32);
    assert_eq!(on, used);

    // Fault (a host that stops writing: the boards' watchdogs expire):
    // power is refused with the fault named; off is allowed.
    ok(&c
        .command(r#"{"action":"inject","fault":"stop-host"}"#)
        .await);
    let mut polls = 0;
    while c.state().await["state"] != "fault" {
        polls += 1;
        assert!(polls < 100_000, "no fault");
        tokio::task::yield_now().await;
    }
    refused(
        &c.command(r#"{"action":"amplifiers","on":true}"#).await,
        "fault",
    );
    refused(&c.command(r#"{"action":"relay","on":true}"#).await, "fault");
    ok(&c.command(r#"{"action":"amplifiers","on":false}"#).await);
    ok(&c.command(r#"{"action":"clear_fault"}"#).await);
    let found = ok(&c.command(r#"{"action":"configure"}"#).await);
    assert!(
        found.contains("boards 0-7 kept as this program left them"),
        "{found}"
    );
    // Disable says what the power-down found.
    assert_eq!(
        ok(&c.command(r#"{"action":"disable"}"#).await),
        "amplifiers and motor power off on boards 0-7"
    );
    let (_, exit) = c.stop().await;
    assert_eq!(
        exit.to_string(),
        "amplifiers and motor power off on boards 0-7"
    );
}
