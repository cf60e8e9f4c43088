//! The stop signals of every long-running subcommand (serve, replay, send, demo):
//! SIGINT (Ctrl-C), SIGTERM (systemd, `docker stop`, Slurm's `scancel`) and SIGHUP (the
//! terminal went away) become [`Shutdown::trigger_by`] with the signal's name.
//!
//! The handlers run on a thread of their own (with a one-thread tokio runtime), so a
//! synchronous command such as replay, whose render loop polls the signal, gets them
//! as well as the async ones. Once installed they replace the default action (immediate
//! death) for the rest of the process.

use hilcam_core::Shutdown;
use tokio::signal::unix::{Signal, SignalKind, signal};

/// What a signal after the first does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Again {
    /// Nothing: the stop under way finishes (serve closes its clients on a frame boundary).
    Ignore,
    /// Exit at once with 128 + the signal (replay: frames are written whole or not at
    /// all, so even this leaves no partial frame).
    ExitNow,
}

/// Install the handlers and return the [`Shutdown`] they trigger.
///
/// # Errors
/// The runtime, a handler or the thread could not be set up.
pub fn stop_on_signals(again: Again) -> std::io::Result<Shutdown> {
    let rt = tokio::runtime::Builder::new_current_thread().enable_io().build()?;
    // Registered here, before returning: a signal from now on stops rather than kills.
    let signals = {
        let _in_rt = rt.enter();
        [
            (signal(SignalKind::interrupt())?, "SIGINT", libc::SIGINT),
            (signal(SignalKind::terminate())?, "SIGTERM", libc::SIGTERM),
            (signal(SignalKind::hangup())?, "SIGHUP", libc::SIGHUP),
        ]
    };
    let shutdown = Shutdown::new();
    let trigger = shutdown.clone();
    std::thread::Builder::new().name("hilcam-signals".into()).spawn(move || {
        rt.block_on(async move {
            let [mut int, mut term, mut hup] = signals;
            let mut first = true;
            loop {
                let (name, number) = next(&mut int, &mut term, &mut hup).await;
                if first {
                    trigger.trigger_by(name);
                    first = false;
                } else if again == Again::ExitNow {
                    // SAFETY: _exit ends the process without running anything else.
                    unsafe { libc::_exit(128 + number) }
                }
            }
        })
    })?;
    Ok(shutdown)
}

/// The signal that triggered `s`, by name (for messages).
pub fn cause(s: &Shutdown) -> &'static str {
    s.cause().unwrap_or("a stop request")
}

type Handler = (Signal, &'static str, libc::c_int);

/// The next of the three signals: its name and number.
async fn next(int: &mut Handler, term: &mut Handler, hup: &mut Handler) -> (&'static str, libc::c_int) {
    tokio::select! {
        _ = int.0.recv() => (int.1, int.2),
        _ = term.0.recv() => (term.1, term.2),
        _ = hup.0.recv() => (hup.1, hup.2),
    }
}
