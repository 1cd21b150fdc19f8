//! The async shell around the controlling-operator rule ([`super::slot`]): a claim that waits for
//! a takeover without polling, and the guard that gives the slot back when a session ends.
//!
//! A takeover closes the old connection and then sleeps on a [`Notify`] that the old session's
//! release rings, bounded by the takeover deadline; each wake asks the state machine again. The
//! deadline is on tokio's clock, the one its timer sleeps on.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use rustls_pki_types::CertificateDer;
use tokio::sync::Notify;
use transport::CloseCode;

use super::slot::{ClaimError, Claimed, Contender, Grant, Reason, Released, Replace, Slot, Ticket};

/// A handle on an operator's connection that can be told it was replaced.
pub(super) trait Replaceable: Clone {
    /// Closes this connection because `newer` takes over, for `why` (the same operator again,
    /// or this one silent past the silence limit).
    fn replaced_by(&self, newer: &Self, operator: &str, why: Reason);
}

/// The slot shared by every connection task, and the bell its releases ring.
#[derive(Debug)]
pub(super) struct Claims<B, C> {
    slot: Mutex<Slot<B, C>>,
    /// Rung when a release hands the slot to a waiting takeover (one waits at a time, so
    /// `notify_one`, whose permit survives a ring that comes before the wait).
    handed_over: Notify,
    /// Zero of the state machine's clock.
    origin: tokio::time::Instant,
}

/// The slot held for one session; given back when dropped (also on error or cancellation).
#[derive(Debug)]
pub(super) struct Control<B, C: Replaceable> {
    claims: Arc<Claims<B, C>>,
    grant: Option<Grant<B>>,
}

impl<B, C: Replaceable> Claims<B, C> {
    /// A free slot holding `bells`; a takeover waits at most `takeover_wait`; a holder silent
    /// for `silence_limit` is replaced by any contender ([`Slot::new`]).
    pub(super) fn new(
        bells: B,
        takeover_wait: Duration,
        silence_limit: Duration,
    ) -> Arc<Claims<B, C>> {
        Arc::new(Claims {
            slot: Mutex::new(Slot::new(bells, takeover_wait, silence_limit)),
            handed_over: Notify::new(),
            origin: tokio::time::Instant::now(),
        })
    }

    /// Takes the slot for `contender`, or says why not ([`Slot::claim`]). If the contender is
    /// the operator in control again, or the one in control has been silent past the silence
    /// limit, the old connection is closed and this waits (at most the takeover wait) for the
    /// old session to end.
    pub(super) async fn claim(
        self: &Arc<Self>,
        contender: Contender<C>,
    ) -> Result<Control<B, C>, ClaimError> {
        let newer = contender.connection.clone();
        let name = contender.name.clone();
        let (ticket, old, why) = match self.lock().claim(contender, self.now_ns())? {
            Claimed::Granted(grant) => return Ok(self.control(grant)),
            Claimed::Replacing { ticket, old, why } => (ticket, old, why),
        };
        old.replaced_by(&newer, &name, why);
        let mut waiting = Waiting {
            claims: self,
            ticket: Some(ticket),
        };
        loop {
            let handed_over = self.handed_over.notified();
            let now_ns = self.now_ns();
            let until_ns = match self.lock().replace(ticket, now_ns) {
                Ok(Replace::Waiting { until_ns }) => until_ns,
                Ok(Replace::Granted(grant)) => {
                    waiting.ticket = None;
                    return Ok(self.control(grant));
                }
                Err(refused) => {
                    waiting.ticket = None;
                    return Err(refused);
                }
            };
            let left = Duration::from_nanos(until_ns.saturating_sub(now_ns).unsigned_abs());
            let _ = tokio::time::timeout(left, handed_over).await;
        }
    }

    fn control(self: &Arc<Self>, grant: Grant<B>) -> Control<B, C> {
        Control {
            claims: Arc::clone(self),
            grant: Some(grant),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Slot<B, C>> {
        self.slot.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Now on the state machine's clock \[ns since `origin`\].
    fn now_ns(&self) -> i64 {
        i64::try_from(self.origin.elapsed().as_nanos()).unwrap_or(i64::MAX)
    }
}

impl<B, C: Replaceable> Control<B, C> {
    /// The loop's outbox doorbells, the session's while it is in control (`None` only while the
    /// guard is being dropped).
    pub(super) fn bells(&mut self) -> Option<&mut B> {
        self.grant.as_mut().map(|grant| &mut grant.bells)
    }

    /// A handle the session tells when it hears from its operator ([`Slot::heard`]); `None`
    /// only while the guard is being dropped.
    pub(super) fn liveness(&self) -> Option<Liveness<B, C>> {
        let grant = self.grant.as_ref()?;
        Some(Liveness {
            claims: Arc::clone(&self.claims),
            ticket: grant.ticket(),
        })
    }
}

/// Tells the slot that the session holding it heard from its operator.
#[derive(Debug)]
pub(super) struct Liveness<B, C> {
    claims: Arc<Claims<B, C>>,
    ticket: Ticket,
}

impl<B, C: Replaceable> Liveness<B, C> {
    /// The session heard from its operator just now.
    pub(super) fn heard(&self) {
        let now_ns = self.claims.now_ns();
        self.claims.lock().heard(self.ticket, now_ns);
    }
}

impl<B, C: Replaceable> Drop for Control<B, C> {
    fn drop(&mut self) {
        let Some(grant) = self.grant.take() else {
            return;
        };
        let released = self.claims.lock().release(grant);
        match released {
            Ok(Released::Free) => {}
            Ok(Released::HandedOver) => self.claims.handed_over.notify_one(),
            Err(_) => {
                tracing::error!("a session released a controlling-operator slot it did not hold")
            }
        }
    }
}

/// A takeover in progress: withdrawn if the claim is dropped before it is through (its task
/// cancelled), so that a slot handed to it is not lost with its doorbells.
struct Waiting<'a, B, C: Replaceable> {
    claims: &'a Claims<B, C>,
    ticket: Option<Ticket>,
}

impl<B, C: Replaceable> Drop for Waiting<'_, B, C> {
    fn drop(&mut self) {
        if let Some(ticket) = self.ticket {
            self.claims.lock().withdraw(ticket);
        }
    }
}

impl Replaceable for quinn::Connection {
    fn replaced_by(&self, newer: &Self, operator: &str, why: Reason) {
        let (old, new) = (self.remote_address(), newer.remote_address());
        let reason = match why {
            Reason::Restarted => {
                tracing::info!(%old, %new, operator,
                    "the operator in control connected again: replacing its old connection");
                "replaced by a newer connection with the same certificate".to_owned()
            }
            Reason::Silent { silent } => {
                tracing::warn!(%old, %new, operator, ?silent,
                    "nothing heard from the operator in control for {silent:?}: \
                     taking its connection as dead and giving control to another");
                format!("nothing heard for {silent:?}: control given to another operator")
            }
        };
        self.close(CloseCode::Replaced.code(), reason.as_bytes());
    }
}

/// The certificate the peer presented in the TLS handshake (DER), if any.
pub(super) fn peer_certificate(connection: &quinn::Connection) -> Option<Vec<u8>> {
    let chain = connection
        .peer_identity()?
        .downcast::<Vec<CertificateDer<'static>>>()
        .ok()?;
    chain.first().map(|c| c.to_vec())
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use tokio::time::Instant;

    use super::*;
    use crate::net::slot::TAKEOVER_WAIT;

    /// A connection that records who replaced it.
    #[derive(Clone, Debug)]
    struct Fake {
        name: &'static str,
        replaced_by: Arc<Mutex<Option<&'static str>>>,
    }

    impl Fake {
        fn new(name: &'static str) -> Fake {
            Fake {
                name,
                replaced_by: Arc::default(),
            }
        }

        fn replaced_by(&self) -> Option<&'static str> {
            *self
                .replaced_by
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
        }
    }

    impl Replaceable for Fake {
        fn replaced_by(&self, newer: &Self, _operator: &str, _why: Reason) {
            *self
                .replaced_by
                .lock()
                .unwrap_or_else(PoisonError::into_inner) = Some(newer.name);
        }
    }

    fn operator(name: &str, certificate: &[u8], connection: &Fake) -> Contender<Fake> {
        Contender {
            name: name.to_owned(),
            certificate: Some(certificate.to_vec()),
            connection: connection.clone(),
        }
    }

    fn claims() -> Arc<Claims<&'static str, Fake>> {
        Claims::new("bells", TAKEOVER_WAIT, Duration::from_secs(1))
    }

    #[tokio::test(start_paused = true)]
    async fn a_takeover_wakes_when_the_old_session_ends() {
        let claims = claims();
        let (a1, a2) = (Fake::new("a1"), Fake::new("a2"));
        let mut old = claims.claim(operator("alice", b"A", &a1)).await.unwrap();
        assert_eq!(old.bells().copied(), Some("bells"));
        let start = Instant::now();
        let waiting = tokio::spawn({
            let claims = Arc::clone(&claims);
            let contender = operator("alice", b"A", &a2);
            async move { claims.claim(contender).await }
        });
        tokio::time::sleep(Duration::from_millis(700)).await;
        assert_eq!(a1.replaced_by(), Some("a2"));
        drop(old);
        let mut new = waiting.await.unwrap().unwrap();
        // Woken by the release itself, not by a poll or the deadline (the clock is paused).
        assert_eq!(start.elapsed(), Duration::from_millis(700));
        assert_eq!(new.bells().copied(), Some("bells"));
        let refused = claims.claim(operator("bob", b"B", &Fake::new("b1"))).await;
        assert_eq!(
            refused.unwrap_err(),
            ClaimError::Busy {
                holder: "alice".to_owned()
            }
        );
    }

    #[tokio::test(start_paused = true)]
    async fn a_takeover_gives_up_at_the_deadline() {
        let claims = claims();
        let (a1, a2) = (Fake::new("a1"), Fake::new("a2"));
        let old = claims.claim(operator("alice", b"A", &a1)).await.unwrap();
        let start = Instant::now();
        let refused = claims
            .claim(operator("alice", b"A", &a2))
            .await
            .unwrap_err();
        assert_eq!(start.elapsed(), TAKEOVER_WAIT);
        assert_eq!(
            refused,
            ClaimError::TakeoverTimedOut {
                holder: "alice".to_owned(),
                waited: TAKEOVER_WAIT
            }
        );
        assert_eq!(a1.replaced_by(), Some("a2"));
        // The old session still holds the slot; once it ends the slot is free.
        drop(old);
        let mut bob = claims
            .claim(operator("bob", b"B", &Fake::new("b1")))
            .await
            .unwrap();
        assert_eq!(bob.bells().copied(), Some("bells"));
    }

    #[tokio::test(start_paused = true)]
    async fn a_cancelled_takeover_loses_neither_the_slot_nor_the_doorbells() {
        for release_first in [false, true] {
            let claims = claims();
            let old = claims
                .claim(operator("alice", b"A", &Fake::new("a1")))
                .await
                .unwrap();
            let waiting = tokio::spawn({
                let claims = Arc::clone(&claims);
                let contender = operator("alice", b"A", &Fake::new("a2"));
                async move { claims.claim(contender).await }
            });
            tokio::time::sleep(Duration::from_millis(100)).await;
            if release_first {
                // Handed over, but the contender is cancelled before it picks the slot up.
                drop(old);
                waiting.abort();
                assert!(waiting.await.unwrap_err().is_cancelled());
            } else {
                waiting.abort();
                assert!(waiting.await.unwrap_err().is_cancelled());
                drop(old);
            }
            let mut bob = claims
                .claim(operator("bob", b"B", &Fake::new("b1")))
                .await
                .unwrap();
            assert_eq!(
                bob.bells().copied(),
                Some("bells"),
                "release first: {release_first}"
            );
        }
    }
}
