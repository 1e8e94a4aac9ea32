//! `fbwag router`: MAVLink routing alone, between any number of links
//! (serial, UDP in/out, TCP client/server), by the MAVLink routing rules
//! (see `mavframe::route`): addressed frames go where their addressee was
//! seen, broadcasts and unknown ids everywhere but back; frames are
//! forwarded untouched, so signed frames stay verifiable end to end.

use super::{Clock, Limiter, Log};
use fbwag_dialect::mavframe::router::{LinkConfig, Router, RouterEvent};
use fbwag_dialect::{Dialect, Endpoint};
use std::io;
use std::time::Duration;

/// Runs the router for `duration` (or until killed), printing a line per
/// link change and a summary every `report` seconds.
pub fn run_router(
    endpoints: Vec<Endpoint>,
    duration: Option<Duration>,
    report: Duration,
    out: Box<dyn io::Write + Send>,
) -> io::Result<()> {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async move {
            let clock = Clock::start();
            let mut log = Log::new(out, clock, "router");
            let mut router = Router::<Dialect>::new();
            for e in &endpoints {
                router
                    .add(LinkConfig::new(e.clone()))
                    .await
                    .map_err(|err| io::Error::new(err.kind(), format!("cannot open {e}: {err}")))?;
                log.line(&format!("link {e}"));
            }
            let end = duration.map(|d| tokio::time::Instant::now() + d);
            let mut next_report = tokio::time::Instant::now() + report;
            let mut errors = Limiter::new(5, Duration::from_secs(10));
            let (mut frames, mut forwarded) = (0u64, 0u64);
            loop {
                let wake = end.map_or(next_report, |e| e.min(next_report));
                tokio::select! {
                    event = router.recv() => match event {
                        Some(RouterEvent::Frame(f)) => {
                            frames += 1;
                            forwarded += router.forward(&f).iter().count() as u64;
                        }
                        Some(RouterEvent::LinkDown { link, error }) => {
                            let name = router.endpoint(link).map(|e| e.to_string()).unwrap_or_default();
                            errors.log(&mut log, "link errors", || {
                                format!("link {name} failed ({error}); opening it again every second")
                            });
                        }
                        Some(RouterEvent::LinkUp { link }) => {
                            let name = router.endpoint(link).map(|e| e.to_string()).unwrap_or_default();
                            log.line(&format!("link {name} open again"));
                        }
                        None => break,
                    },
                    _ = tokio::time::sleep_until(wake) => {
                        if end.is_some_and(|e| tokio::time::Instant::now() >= e) {
                            break;
                        }
                        next_report += report;
                        log.line(&format!("{frames} frames in, {forwarded} sent on"));
                    }
                }
            }
            log.line(&format!("done: {frames} frames in, {forwarded} sent on"));
            router.shutdown(Duration::from_secs(1)).await;
            Ok(())
        })
}
