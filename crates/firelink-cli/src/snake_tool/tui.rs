//! The terminal UI of the snake tool: the selected node's seven channels
//! redrawn ten times a second, keys for the common actions and a prompt
//! for any command.

use std::io::Write;
use std::time::{Duration, Instant};

use crossterm::event::{self, Event, KeyCode, KeyEvent};
use crossterm::{cursor, execute, terminal};

use firelink_host::Port;

use firelink_testbed::snake::tool::{HELP, KEYS, Session, key_command, outcome_line, render};

use crate::error::CliError;

/// Run the UI until `q`.
pub fn run<P: Port>(session: &mut Session<P>, out: &mut impl Write) -> Result<(), CliError> {
    terminal::enable_raw_mode()?;
    execute!(out, terminal::EnterAlternateScreen, cursor::Hide)?;
    let result = ui(session, out);
    let _ = execute!(out, cursor::Show, terminal::LeaveAlternateScreen);
    let _ = terminal::disable_raw_mode();
    result
}

fn ui<P: Port>(session: &mut Session<P>, out: &mut impl Write) -> Result<(), CliError> {
    let mut message = String::from("type : then help for every command");
    let mut prompt: Option<String> = None;
    let mut last = Instant::now() - Duration::from_secs(1);
    // SIGTERM / SIGHUP end the tool; the nodes are powered down as the
    // session's Snake system is dropped.
    let stop = firelink_host::stop::StopRequest::process();
    loop {
        if stop.is_requested() {
            return Ok(());
        }
        if last.elapsed() >= Duration::from_millis(100) {
            let elapsed = last.elapsed().min(Duration::from_millis(500));
            last = Instant::now();
            // On the simulated bus, time moves as the UI waits.
            let _ = session.command(&format!("wait {}", elapsed.as_secs_f64() * 1e3));
            let frame = match session.view() {
                Ok(v) => render(&v, session.channel()),
                Err(e) => format!("board {}: {e}\n", session.board()),
            };
            execute!(
                out,
                cursor::MoveTo(0, 0),
                terminal::Clear(terminal::ClearType::All)
            )?;
            let line = match &prompt {
                Some(p) => format!(":{p}"),
                None => message.clone(),
            };
            let text = format!(
                "firelink snake-tool  boards {:?}  channel {}\n{frame}\n{KEYS}\n{line}\n",
                session.boards(),
                session.channel()
            );
            write!(out, "{}", text.replace('\n', "\r\n"))?;
            out.flush()?;
        }
        if !event::poll(Duration::from_millis(20))? {
            continue;
        }
        let Event::Key(KeyEvent {
            code, modifiers, ..
        }) = event::read()?
        else {
            continue;
        };
        // In raw mode Ctrl-C is a key, not a signal.
        if code == KeyCode::Char('c') && modifiers.contains(event::KeyModifiers::CONTROL) {
            return Ok(());
        }
        last = Instant::now() - Duration::from_secs(1);
        if let Some(p) = prompt.as_mut() {
            match code {
                KeyCode::Enter => {
                    let line = std::mem::take(p);
                    prompt = None;
                    message = if line.trim() == "help" {
                        HELP.replace('\n', " | ")
                    } else {
                        outcome_line(session.command(&line))
                    };
                }
                KeyCode::Esc => prompt = None,
                KeyCode::Backspace => {
                    p.pop();
                }
                KeyCode::Char(c) => p.push(c),
                _ => {}
            }
            continue;
        }
        let boards = session.boards();
        let at = boards
            .iter()
            .position(|b| *b == session.board())
            .unwrap_or(0);
        let command = match code {
            KeyCode::Char('q') | KeyCode::Esc => return Ok(()),
            KeyCode::Char(':') => {
                prompt = Some(String::new());
                continue;
            }
            KeyCode::Left => format!("channel {}", session.channel().saturating_sub(1).max(1)),
            KeyCode::Right => format!("channel {}", (session.channel() + 1).min(7)),
            KeyCode::Up => format!("board {}", boards[at.saturating_sub(1)]),
            KeyCode::Down => format!("board {}", boards[(at + 1).min(boards.len() - 1)]),
            KeyCode::Char(c) => match session.view() {
                Ok(view) => match key_command(&view, session.channel(), c) {
                    Some(cmd) => cmd,
                    None => continue,
                },
                Err(e) => {
                    message = e.to_string();
                    continue;
                }
            },
            _ => continue,
        };
        message = outcome_line(session.command(&command));
    }
}
