//! A page that can switch motor power on: requests without the token (in
//! the header or the cookie, never the URL) or from another origin are
//! refused and change nothing; the right ones work, and a command is
//! answered with its outcome (409 with the reason when the robot's state
//! refuses it). The same for the Snake and MAHRU views, whose commands
//! are checked before they reach the robot (400 with the reason) and reach
//! it when right (the state shows them). Raw HTTP over loopback, against
//! the console in process on the simulated bus. Nothing here is timed: waits are bounded only so
//! that a broken build fails instead of hanging.

use std::net::SocketAddr;
use std::time::Duration;

use serde_json::Value;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use firelink_testbed::loop_outcome::LoopExit;
use firelink_testbed::port_spec::PortSpec;
use firelink_web::server::cookie_name;
use firelink_web::{RobotKind, Running, WebOptions, serve, start};

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
        Console::start_robot(RobotKind::Dvrk, "1ms", allow_origins).await
    }

    async fn start_robot(robot: RobotKind, period: &str, allow_origins: Vec<String>) -> Console {
        let options = WebOptions {
            robot,
            port: PortSpec::SIM,
            config: None,
            period: period.parse().unwrap(),
            watchdog: firelink_host::WatchdogSetting::default(),
            timeout: firelink_testbed::rig::UDP_TIMEOUT,
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
    let info = r.json();
    assert_eq!(info["joints"].as_array().map(Vec::len), Some(28));
    // Started with a period of 1 ms: the rate is derived from it.
    assert_eq!(
        (info["period_us"].as_f64(), info["rate_hz"].as_f64()),
        (Some(1000.0), Some(1000.0))
    );
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

/// Poll the state until `done` holds (bounded by [`HANG`] only).
async fn state_until(c: &Console, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    let waited = tokio::time::timeout(HANG, async {
        loop {
            let st = c.state().await;
            if done(&st) {
                return st;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await;
    waited.unwrap_or_else(|_| panic!("the state never showed {what}"))
}

/// The checks every robot's console makes: no token (or a wrong one, or
/// one in the URL) reveals or changes nothing; another origin changes
/// nothing; the right ones work.
async fn robot_console_checks_token_and_origin(c: &Console, harmless: &str) {
    let (addr, host, own) = (c.addr, c.host(), c.own());
    let origin = format!("Origin: {own}\r\n");
    for path in ["/api/state", "/api/info"] {
        for extra in ["", "X-Firelink-Token: 0000\r\n"] {
            let r = request(addr, &get(&host, path, extra)).await;
            assert_eq!(r.status, 403, "{path} {extra:?}: {}", r.body);
        }
        let in_url = format!("{path}?token={}", c.token);
        let r = request(addr, &get(&host, &in_url, &c.token_header())).await;
        assert_eq!(r.status, 403, "{in_url}");
        assert!(r.body.contains("never in the URL"), "{}", r.body);
        for extra in [c.token_header(), c.cookie()] {
            let r = request(addr, &get(&host, path, &extra)).await;
            assert_eq!(r.status, 200, "{path}: {}", r.body);
        }
    }
    for extra in [
        origin.clone(),
        format!("X-Firelink-Token: 0000\r\n{origin}"),
        c.token_header(),
        format!("{}Origin: http://evil.example\r\n", c.token_header()),
        format!("{}Origin: null\r\n", c.cookie()),
    ] {
        let r = request(addr, &post(&host, "/api/command", &extra, harmless)).await;
        assert_eq!(r.status, 403, "{extra:?}: {}", r.body);
    }
    let r = c.command(harmless).await;
    assert_eq!(r.status, 200, "{}", r.body);
    // The page and its assets need nothing.
    for path in ["/", "/app.js", "/robots.js", "/app.css"] {
        let r = request(addr, &get(&host, path, "")).await;
        assert_eq!(r.status, 200, "{path}");
    }
}

/// Malformed and unknown commands are refused with 400 and a reason
/// before they reach the robot.
async fn refused_as_malformed(c: &Console, bodies: &[(&str, &str)]) {
    for (body, why) in bodies {
        let r = c.command(body).await;
        assert_eq!(r.status, 400, "{body}: {}", r.body);
        let detail = r.json()["detail"].as_str().unwrap_or("").to_string();
        assert!(detail.contains(why), "{body}: {detail:?} lacks {why:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_snake_console_shows_36_axes_and_drives_its_channels() {
    let c = Console::start_robot(RobotKind::Snake, "1kHz", Vec::new()).await;
    robot_console_checks_token_and_origin(&c, r#"{"action":"disable"}"#).await;
    let r = request(c.addr, &get(&c.host(), "/api/info", &c.token_header())).await;
    let info = r.json();
    assert_eq!(info["robot"], "snake");
    assert_eq!(info["joints"].as_array().map(Vec::len), Some(36));
    assert_eq!(info["nodes"], serde_json::json!([0, 1, 2, 3, 4, 5]));
    // Started with a rate of 1 kHz: a period of 1 ms.
    assert_eq!(
        (info["period_us"].as_f64(), info["rate_hz"].as_f64()),
        (Some(1000.0), Some(1000.0))
    );
    let st = state_until(&c, "36 axes", |s| {
        s["axes"].as_array().is_some_and(|a| a.len() == 36)
    })
    .await;
    assert_eq!(st["robot"], "snake");
    assert_eq!(st["state"], "unconfigured");
    assert_eq!(st["nodes"].as_array().map(Vec::len), Some(6));
    // Every channel as the node setup left it: the nominal wiper, torque mode.
    for a in st["axes"].as_array().unwrap() {
        assert_eq!(a["wiper"], 375, "{a}");
        assert_eq!(a["speed_mode"], false, "{a}");
    }
    let axis = 9;
    let where_ = (
        st["axes"][axis]["node"].clone(),
        st["axes"][axis]["channel"].clone(),
    );
    refused_as_malformed(
        &c,
        &[
            ("not json", "bad command"),
            (r#"{"action":"fly"}"#, "unknown variant `fly`"),
            (r#"{"action":"mode","speed":true}"#, "missing field `axis`"),
            (
                r#"{"action":"mode","axis":36,"speed":true}"#,
                "axis 36 does not exist",
            ),
            (r#"{"action":"mode","axis":-1,"speed":true}"#, "bad command"),
            (
                r#"{"action":"wiper","axis":0,"wiper":1024}"#,
                "wiper 1024: 0..=1023",
            ),
            (
                r#"{"action":"eeprom_read","axis":0,"word":16}"#,
                "EEPROM word 16",
            ),
            (
                r#"{"action":"eeprom_read","axis":0,"word":15,"float":true}"#,
                "for a float",
            ),
            (
                r#"{"action":"eeprom_write","axis":0,"word":1,"value":70000}"#,
                "0..=65535",
            ),
            (
                r#"{"action":"eeprom_write","axis":0,"word":1,"value":1.5}"#,
                "0..=65535",
            ),
            (r#"{"action":"jog","axis":0,"delta":5}"#, "at most 0.5"),
        ],
    )
    .await;
    // The torque/speed switch reaches the node and is read back.
    let r = c
        .command(&format!(
            r#"{{"action":"mode","axis":{axis},"speed":true}}"#
        ))
        .await;
    assert_eq!(r.status, 200, "{}", r.body);
    let detail = r.json()["detail"].as_str().unwrap_or("").to_string();
    assert!(
        detail.contains(&format!(
            "node {} channel {}: speed mode (read back)",
            where_.0, where_.1
        )),
        "{detail}"
    );
    let st = state_until(&c, "speed mode", |s| s["axes"][axis]["speed_mode"] == true).await;
    assert_eq!(st["axes"][axis - 1]["speed_mode"], false);
    // The wiper, and the gain it sets.
    let r = c
        .command(&format!(
            r#"{{"action":"wiper","axis":{axis},"wiper":649}}"#
        ))
        .await;
    assert_eq!(r.status, 200, "{}", r.body);
    // The state read after the outcome shows it (the loop hands the frame
    // over before the outcome).
    let st = c.state().await;
    assert_eq!(st["axes"][axis]["wiper"], 649);
    let gain = st["axes"][axis]["gain"].as_f64().unwrap();
    let w = 649.0 / 1023.0;
    assert!(
        (gain - (12.1 + 10.0 * w) / (1.5 + 10.0 * (1.0 - w))).abs() < 1e-9,
        "{gain}"
    );
    // EEPROM: protected as the nodes start; unprotected, a word and a
    // float written and read back; protected again, a write refused.
    assert_eq!(st["axes"][axis]["write_protect"], true);
    let r = c
        .command(&format!(
            r#"{{"action":"write_protect","axis":{axis},"on":false}}"#
        ))
        .await;
    assert_eq!(r.status, 200, "{}", r.body);
    state_until(&c, "unprotected", |s| {
        s["axes"][axis]["write_protect"] == false
    })
    .await;
    let r = c
        .command(&format!(
            r#"{{"action":"eeprom_write","axis":{axis},"word":3,"value":4660}}"#
        ))
        .await;
    assert_eq!(r.status, 200, "{}", r.body);
    let r = c
        .command(&format!(
            r#"{{"action":"eeprom_read","axis":{axis},"word":3}}"#
        ))
        .await;
    assert!(
        r.json()["detail"]
            .as_str()
            .unwrap_or("")
            .contains("word 3: 4660 (0x1234)"),
        "{}",
        r.body
    );
    let r = c
        .command(&format!(
            r#"{{"action":"eeprom_write","axis":{axis},"word":4,"value":2.5,"float":true}}"#
        ))
        .await;
    assert_eq!(r.status, 200, "{}", r.body);
    let r = c
        .command(&format!(
            r#"{{"action":"eeprom_read","axis":{axis},"word":4,"float":true}}"#
        ))
        .await;
    assert!(
        r.json()["detail"]
            .as_str()
            .unwrap_or("")
            .contains("float at word 4: 2.5"),
        "{}",
        r.body
    );
    let r = c
        .command(&format!(
            r#"{{"action":"write_protect","axis":{axis},"on":true}}"#
        ))
        .await;
    assert_eq!(r.status, 200, "{}", r.body);
    let r = c
        .command(&format!(
            r#"{{"action":"eeprom_write","axis":{axis},"word":3,"value":1}}"#
        ))
        .await;
    assert_eq!(r.status, 500, "{}", r.body);
    assert!(r.body.contains("write protection"), "{}", r.body);
    // Motion is refused until the robot is enabled and homed.
    let r = c.command(r#"{"action":"jog","axis":0,"delta":0.1}"#).await;
    assert_eq!(r.status, 409, "{}", r.body);
    assert!(r.body.contains("needs an enabled robot"), "{}", r.body);
    // Back to torque mode and the nominal wiper, then the lifecycle.
    for body in [
        format!(r#"{{"action":"mode","axis":{axis},"speed":false}}"#),
        format!(r#"{{"action":"wiper","axis":{axis},"wiper":375}}"#),
        r#"{"action":"configure"}"#.to_string(),
        r#"{"action":"power_on"}"#.to_string(),
    ] {
        let r = c.command(&body).await;
        assert_eq!(r.status, 200, "{body}: {}", r.body);
    }
    // Settings are refused with the amplifiers on.
    let r = c
        .command(&format!(
            r#"{{"action":"mode","axis":{axis},"speed":true}}"#
        ))
        .await;
    assert_eq!(r.status, 409, "{}", r.body);
    assert!(r.body.contains("disable first"), "{}", r.body);
    for body in [r#"{"action":"home"}"#, r#"{"action":"enable"}"#] {
        let r = c.command(body).await;
        assert_eq!(r.status, 200, "{body}: {}", r.body);
    }
    let st = state_until(&c, "active", |s| s["state"] == "active").await;
    assert_eq!(st["homed"], true);
    assert!(
        st["axes"]
            .as_array()
            .unwrap()
            .iter()
            .all(|a| a["amp"] == true),
        "{st}"
    );
    let before = st["axes"][0]["setpoint"].as_f64().unwrap();
    let r = c.command(r#"{"action":"jog","axis":0,"delta":0.05}"#).await;
    assert_eq!(r.status, 200, "{}", r.body);
    state_until(&c, "the jog's end", |s| {
        s["axes"][0]["setpoint"]
            .as_f64()
            .is_some_and(|sp| (sp - before - 0.05).abs() < 1e-9)
    })
    .await;
    // A goal past the axis's soft limits is refused and moves nothing.
    let r = c
        .command(r#"{"action":"move","axis":0,"position":1e300}"#)
        .await;
    assert_eq!(r.status, 409, "{}", r.body);
    assert!(r.body.contains("outside its soft limits"), "{}", r.body);
    let st = state_until(&c, "the refused move", |s| {
        s["axes"][0]["setpoint"].is_number()
    })
    .await;
    let held = st["axes"][0]["setpoint"].as_f64().unwrap();
    assert!((held - before - 0.05).abs() < 1e-9, "{st}");
    let (accepted, exit) = c.stop().await;
    // Every command above but the malformed ones reached the robot.
    assert_eq!(accepted, 20);
    assert!(exit.is_clean(), "{exit}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_mahru_console_shows_14_modules_and_walks_on_command() {
    // Seed 002's period, 2 ms.
    let c = Console::start_robot(RobotKind::Mahru, "2ms", Vec::new()).await;
    robot_console_checks_token_and_origin(&c, r#"{"action":"gait_stop"}"#).await;
    let r = request(c.addr, &get(&c.host(), "/api/info", &c.token_header())).await;
    let info = r.json();
    assert_eq!(info["robot"], "mahru");
    let modules = info["modules"].as_array().unwrap();
    assert_eq!(modules.len(), 14);
    assert_eq!(
        modules
            .iter()
            .filter(|m| m["kind"] == "force_torque")
            .count(),
        4
    );
    refused_as_malformed(
        &c,
        &[
            ("{", "bad command"),
            (r#"{"action":"dance"}"#, "unknown variant `dance`"),
            (r#"{"no_action":1}"#, "missing field `action`"),
        ],
    )
    .await;
    // Disabled: the gait is refused.
    let r = c.command(r#"{"action":"gait_start"}"#).await;
    assert_eq!(r.status, 409, "{}", r.body);
    assert!(r.body.contains("enable first"), "{}", r.body);
    let r = c.command(r#"{"action":"enable"}"#).await;
    assert_eq!(r.status, 200, "{}", r.body);
    let st = state_until(&c, "periods run", |s| {
        s["budget"]["periods"].as_u64() > Some(10)
    })
    .await;
    assert_eq!(st["state"], "enabled");
    let b = &st["budget"];
    assert_eq!(b["period_us"], 2000.0);
    let busy = b["busy_us"].as_f64().unwrap();
    let parts = ["read_us", "compute_us", "write_us"].map(|k| b[k].as_f64().unwrap());
    assert!(parts.iter().all(|&p| p > 0.0), "{b}");
    assert!(busy >= parts.iter().sum::<f64>(), "{b}");
    // The sensors read a wrench (the feet carry the body).
    let ft: Vec<&Value> = st["modules"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| {
            m["wrench"]
                .as_array()
                .is_some_and(|w| w.iter().any(|x| x != 0.0))
        })
        .collect();
    assert!(!ft.is_empty(), "{st}");
    assert_eq!(st["gait"]["walking"], false);
    let r = c.command(r#"{"action":"gait_start"}"#).await;
    assert_eq!(r.status, 200, "{}", r.body);
    let st = state_until(&c, "walking", |s| {
        s["gait"]["walking"] == true && s["gait"]["time_s"].as_f64() > Some(0.3)
    })
    .await;
    let phase = st["gait"]["phase"].as_f64().unwrap();
    assert!((0.0..1.0).contains(&phase), "{phase}");
    let r = c.command(r#"{"action":"gait_stop"}"#).await;
    assert_eq!(r.status, 200, "{}", r.body);
    let held = state_until(&c, "holding", |s| s["gait"]["walking"] == false).await;
    let t = held["gait"]["time_s"].as_f64().unwrap();
    let later = state_until(&c, "a later frame", |s| {
        s["t"].as_f64() > held["t"].as_f64()
    })
    .await;
    assert_eq!(later["gait"]["time_s"].as_f64(), Some(t));
    assert_eq!(later["missed"], 0);
    let r = c.command(r#"{"action":"disable"}"#).await;
    assert_eq!(r.status, 200, "{}", r.body);
    assert!(r.body.contains("every module stopped"), "{}", r.body);
    let (accepted, exit) = c.stop().await;
    // Every command above but the malformed ones reached the robot.
    assert_eq!(accepted, 6);
    assert!(exit.is_clean(), "{exit}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_board_loss_on_the_snake_shows_as_a_fault_and_an_unknown_node() {
    let c = Console::start_robot(RobotKind::Snake, "1kHz", Vec::new()).await;
    refused_as_malformed(
        &c,
        &[
            (
                r#"{"action":"inject","fault":"meteor"}"#,
                "one of board-loss, stop-host, following-error",
            ),
            (
                r#"{"action":"inject","fault":"corrupt-query"}"#,
                "cannot be injected here",
            ),
        ],
    )
    .await;
    for action in ["configure", "power_on", "home", "enable"] {
        let r = c.command(&format!(r#"{{"action":"{action}"}}"#)).await;
        assert_eq!(r.status, 200, "{action}: {}", r.body);
    }
    let r = c
        .command(r#"{"action":"inject","fault":"board-loss"}"#)
        .await;
    assert_eq!(r.status, 200, "{}", r.body);
    let st = state_until(&c, "the fault", |s| s["state"] == "fault").await;
    assert!(
        st["fault"]["text"]
            .as_str()
            .unwrap_or("")
            .contains("board 4"),
        "{st}"
    );
    // The frame of the fault's own cycle carries the status latched before
    // the fault path's disable went out; every frame latched after that
    // cycle must show it (a disable that had not landed by the next cycle
    // fails below).
    let st = state_until(&c, "a frame after the fault's cycle", |s| {
        s["fault"]["cycle"]
            .as_u64()
            .is_some_and(|fault| s["cycle"].as_u64() > Some(fault))
    })
    .await;
    assert_eq!(st["nodes"][4]["valid"], false, "{st}");
    // The other nodes answer, every amplifier off (the fault path).
    for n in st["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|n| n["id"] != 4)
    {
        assert_eq!(n["valid"], true, "{n}");
        assert_eq!(n["amps"], 0, "{n}");
    }
    let (_, exit) = c.stop().await;
    // The power-down cannot know node 4's state.
    let pd = exit.power_down.expect("a power-down");
    assert_eq!((pd.unknown, pd.still_on), (1 << 4, 0), "{exit}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_mahru_period_outside_its_configuration_bounds_is_refused_with_the_range() {
    // 50 us is a servo period (10 us to 1 s) but not one MAHRU's
    // configuration allows (100 us to 1 s): refused before anything runs.
    let options = WebOptions {
        robot: RobotKind::Mahru,
        port: PortSpec::SIM,
        config: None,
        period: "50us".parse().unwrap(),
        watchdog: firelink_host::WatchdogSetting::default(),
        timeout: firelink_testbed::rig::UDP_TIMEOUT,
        listen: "127.0.0.1:0".parse().unwrap(),
        allow_origins: Vec::new(),
    };
    let e = start(&options).await.err().expect("refused").to_string();
    assert!(
        e.contains("MAHRU: period 50 us is out of range: 100 to 1000000 us"),
        "{e}"
    );
}
