//! [`Shutdown`]: one stop signal for every thread and task of a daemon.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::Duration;

use tokio::sync::Notify;

/// A stop signal, cheap to clone. Once triggered it stays triggered.
///
/// - the real-time loop polls [`is_triggered`](Self::is_triggered) (one atomic load) every tick;
/// - helper threads sleep in [`wait_timeout`](Self::wait_timeout) (a condition variable: never
///   on a real-time thread);
/// - network tasks await [`wait`](Self::wait).
#[derive(Clone, Debug, Default)]
pub struct Shutdown {
    inner: Arc<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    flag: AtomicBool,
    notify: Notify,
    lock: Mutex<()>,
    wake: Condvar,
}

impl Shutdown {
    /// A signal not yet triggered.
    pub fn new() -> Shutdown {
        Shutdown::default()
    }

    /// Triggers the signal: every waiter returns.
    pub fn trigger(&self) {
        self.inner.flag.store(true, Ordering::SeqCst);
        self.inner.notify.notify_waiters();
        let _guard = self
            .inner
            .lock
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        self.inner.wake.notify_all();
    }

    /// Whether the signal was triggered. Lock-free: for the real-time loop.
    pub fn is_triggered(&self) -> bool {
        self.inner.flag.load(Ordering::SeqCst)
    }

    /// Completes once the signal is triggered (at once if it already was). Cancel-safe.
    pub async fn wait(&self) {
        loop {
            let notified = self.inner.notify.notified();
            tokio::pin!(notified);
            notified.as_mut().enable();
            if self.is_triggered() {
                return;
            }
            notified.await;
        }
    }

    /// Blocks until the signal is triggered or `timeout` passes; returns whether it was
    /// triggered. For helper threads, not the real-time loop.
    pub fn wait_timeout(&self, timeout: Duration) -> bool {
        let guard = self
            .inner
            .lock
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let _unused = self
            .inner
            .wake
            .wait_timeout_while(guard, timeout, |()| !self.is_triggered())
            .unwrap_or_else(PoisonError::into_inner);
        self.is_triggered()
    }

    /// Triggers the signal on Ctrl-C (SIGINT) or SIGTERM, from a small thread running its own
    /// single-threaded tokio runtime (no unsafe signal handler of ours).
    pub fn on_signals(&self) -> io::Result<()> {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?;
        let shutdown = self.clone();
        std::thread::Builder::new()
            .name("signals".to_owned())
            .spawn(move || {
                runtime.block_on(async {
                    let terminate = async {
                        match tokio::signal::unix::signal(
                            tokio::signal::unix::SignalKind::terminate(),
                        ) {
                            Ok(mut s) => {
                                s.recv().await;
                            }
                            Err(_) => std::future::pending::<()>().await,
                        }
                    };
                    tokio::select! {
                        _ = tokio::signal::ctrl_c() => tracing::info!("Ctrl-C: shutting down"),
                        () = terminate => tracing::info!("SIGTERM: shutting down"),
                        () = shutdown.wait() => {}
                    }
                });
                shutdown.trigger();
            })?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_of_waiter_returns_once_triggered() {
        let s = Shutdown::new();
        assert!(!s.is_triggered());
        assert!(!s.wait_timeout(Duration::from_millis(1)));
        let waiter = {
            let s = s.clone();
            std::thread::spawn(move || s.wait_timeout(Duration::from_secs(10)))
        };
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let task = {
            let s = s.clone();
            rt.spawn(async move { s.wait().await })
        };
        std::thread::sleep(Duration::from_millis(20));
        s.trigger();
        assert!(waiter.join().unwrap());
        rt.block_on(task).unwrap();
        assert!(s.is_triggered());
        // Already triggered: returns at once.
        rt.block_on(s.wait());
    }
}
