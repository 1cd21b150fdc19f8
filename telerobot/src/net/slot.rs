//! The one-controlling-operator rule as a state machine: no tokio, no clock, no sockets. Time
//! comes in as `now_ns` (any monotonic clock, the same for every call); the async shell that
//! waits is [`super::claim`].
//!
//! The slot is free (the loop's outbox doorbells wait in it), held by one operator (who has the
//! doorbells), or being handed over to a newer connection of that same operator.
//!
//! - [`Slot::claim`]: a free slot is granted, with the doorbells. A held slot is refused
//!   ([`ClaimError::Busy`]) — unless the contender presents the holder's own certificate (exact
//!   DER): that is the operator in control again (its app restarted before the old connection
//!   timed out), and it takes over: the caller closes the old connection and waits, at most
//!   the takeover wait, for the old session to release. A holder the telerobot has not heard
//!   from (no packet at all, keep-alives included) for the silence limit is dead — killed, or
//!   cut off — and any trusted contender takes over from it the same way: the slot is freed as
//!   soon as someone needs it, not when quinn's idle timeout (5 s) ends the dead connection.
//! - [`Slot::replace`]: asked by the waiting contender each time it wakes: granted once the old
//!   holder has released, still waiting before the deadline, [`ClaimError::TakeoverTimedOut`]
//!   after it.
//! - [`Slot::release`]: the holder gives the slot back with its doorbells; if a takeover is
//!   waiting the slot passes straight to the newcomer (no third connection can slip in between).
//! - [`Slot::withdraw`]: a waiting contender gives up (its task was cancelled).
//! - [`Slot::heard`]: the holder's session says it heard from its operator at `now_ns`.
//!
//! Operators are named to others by [`Contender::name`]; which name that is (today the
//! `operator_name` of the `Hello`) is the caller's choice.

use std::time::Duration;

/// How long a connection presenting the controlling operator's own certificate waits for the
/// old session to end after it was closed: 2 s. The old session's task notices the close at once;
/// this only bounds a session that does not end.
pub(crate) const TAKEOVER_WAIT: Duration = Duration::from_secs(2);

/// How long the holder may be silent before another operator may take the slot over: the
/// longest of 1 s, two keep-alive intervals and two expected round trips.
///
/// Why: an operator in a session sends 1 kHz datagrams, and quinn sends a keep-alive after
/// `keep_alive` (500 ms) of sending nothing, so a live operator is heard from many times a
/// second; 1 s of silence on a 20 ms link is a dead app (SIGKILL: no CONNECTION_CLOSE) or a cut
/// link. Two keep-alive intervals allow one lost keep-alive; two round trips allow the jitter
/// and retransmissions of a long link (2000 ms each way: 8 s, above the idle timeout, which then
/// ends the connection first). An operator that is alive but cut off for longer loses control
/// only if another trusted operator asks for it meanwhile; the robot was held still anyway
/// (commands older than 50 ms hold it).
pub(crate) fn silence_limit(tuning: &transport::LinkTuning) -> Duration {
    let rtt = tuning
        .expected_one_way_delay
        .saturating_mul(2)
        .saturating_add(Duration::from_millis(10));
    Duration::from_secs(1)
        .max(tuning.keep_alive.saturating_mul(2))
        .max(rtt.saturating_mul(2))
}

/// The controlling-operator slot. `B`: the doorbells handed to the session in control; `C`: a
/// handle on an operator's connection (returned to the caller to close when it is replaced).
#[derive(Debug)]
pub(crate) struct Slot<B, C> {
    state: State<B, C>,
    takeover_wait: Duration,
    silence_limit_ns: i64,
    next_ticket: u64,
}

/// One claim (one connection's attempt at the slot).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Ticket(u64);

/// An operator asking for the slot.
#[derive(Clone, Debug)]
pub(crate) struct Contender<C> {
    /// How it is named to an operator refused while it is in control.
    pub(crate) name: String,
    /// The certificate it presented in the TLS handshake (DER), if any.
    pub(crate) certificate: Option<Vec<u8>>,
    /// Its connection.
    pub(crate) connection: C,
}

/// The slot held: the ticket to release it with and the doorbells, the session's until then.
#[derive(Debug)]
pub(crate) struct Grant<B> {
    ticket: Ticket,
    /// The loop's outbox doorbells.
    pub(crate) bells: B,
}

impl<B> Grant<B> {
    /// The ticket the slot is held with.
    pub(crate) fn ticket(&self) -> Ticket {
        self.ticket
    }
}

/// What a successful [`Slot::claim`] says.
#[derive(Debug)]
pub(crate) enum Claimed<B, C> {
    /// The slot was free: in control now.
    Granted(Grant<B>),
    /// The operator in control connected again, or has been silent past the silence limit.
    /// Close `old`, then ask [`Slot::replace`] with `ticket` until it answers (it says how long
    /// to wait for the old session's release).
    Replacing {
        /// The contender's ticket.
        ticket: Ticket,
        /// The connection being replaced.
        old: C,
        /// Why it is replaced.
        why: Reason,
    },
}

/// Why a holder is replaced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Reason {
    /// The contender presented the holder's own certificate: its app restarted.
    Restarted,
    /// Nothing was heard from the holder for `silent` (at least the silence limit).
    Silent {
        /// Since the holder was last heard from.
        silent: Duration,
    },
}

/// What [`Slot::replace`] says.
#[derive(Debug)]
pub(crate) enum Replace<B> {
    /// The old session released: in control now.
    Granted(Grant<B>),
    /// The old session still holds the slot; ask again when it releases or at `until_ns`.
    Waiting {
        /// When the takeover gives up.
        until_ns: i64,
    },
}

/// What [`Slot::release`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Released {
    /// The slot is free again, the doorbells back in it.
    Free,
    /// A takeover was waiting: the slot passed to it; wake the contender.
    HandedOver,
}

/// Why the slot was not given.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub(crate) enum ClaimError {
    /// Another operator is in control.
    #[error("{holder} is in control")]
    Busy {
        /// The operator in control, as it is named to others.
        holder: String,
    },
    /// A connection with the holder's certificate is already taking over from it.
    #[error("{holder} is in control and a newer connection with its certificate is taking over")]
    TakeoverPending {
        /// The operator in control.
        holder: String,
    },
    /// The replaced session did not end within the takeover wait.
    #[error("{holder} is in control: its replaced session did not end within {waited:?}")]
    TakeoverTimedOut {
        /// The operator still in control.
        holder: String,
        /// How long the takeover waited.
        waited: Duration,
    },
    /// [`Slot::replace`] was asked with a ticket that is not taking over (a caller's mistake).
    #[error("this connection is not taking over the slot")]
    NotWaiting,
    /// A transition was interrupted (it cannot panic; this is the honest answer if it ever did).
    #[error("the controlling-operator slot is broken: a transition was interrupted")]
    Broken,
}

impl ClaimError {
    /// The operator in control, for the `Busy` refusal; `None` for a caller's mistake.
    pub(crate) fn holder(&self) -> Option<&str> {
        match self {
            ClaimError::Busy { holder }
            | ClaimError::TakeoverPending { holder }
            | ClaimError::TakeoverTimedOut { holder, .. } => Some(holder),
            ClaimError::NotWaiting | ClaimError::Broken => None,
        }
    }
}

#[derive(Debug)]
enum State<B, C> {
    /// Nobody in control; the doorbells wait here.
    Free(B),
    /// `holder` is in control and has the doorbells; `takeover`, a newer connection with its
    /// certificate, waits for it to release.
    Held {
        holder: Holder<C>,
        takeover: Option<Takeover<C>>,
    },
    /// The holder released while a takeover waited: `newcomer` is in control and picks the
    /// doorbells up at its next [`Slot::replace`].
    HandingOver { newcomer: Holder<C>, bells: B },
    /// Only while [`Slot::step`] computes the next state (the transitions do not panic, so no
    /// caller sees it; if one did, every later call answers [`ClaimError::Broken`]).
    Vacant,
}

#[derive(Debug)]
struct Holder<C> {
    ticket: Ticket,
    contender: Contender<C>,
    /// When its session last heard from it (claimed, or [`Slot::heard`]) \[ns\].
    heard_ns: i64,
}

#[derive(Debug)]
struct Takeover<C> {
    newcomer: Holder<C>,
    until_ns: i64,
}

impl<B, C: Clone> Slot<B, C> {
    /// A free slot holding `bells`; a takeover waits at most `takeover_wait` ([`TAKEOVER_WAIT`]);
    /// a holder silent for `silence_limit` ([`silence_limit`]) is replaced by any contender.
    pub(crate) fn new(bells: B, takeover_wait: Duration, silence_limit: Duration) -> Slot<B, C> {
        Slot {
            state: State::Free(bells),
            takeover_wait,
            silence_limit_ns: nanos(silence_limit),
            next_ticket: 0,
        }
    }

    /// `contender` asks for the slot at `now_ns`.
    pub(crate) fn claim(
        &mut self,
        contender: Contender<C>,
        now_ns: i64,
    ) -> Result<Claimed<B, C>, ClaimError> {
        self.next_ticket += 1;
        let ticket = Ticket(self.next_ticket);
        let wait_ns = nanos(self.takeover_wait);
        let silence_limit_ns = self.silence_limit_ns;
        let newcomer = |contender| Holder {
            ticket,
            contender,
            heard_ns: now_ns,
        };
        self.step(|state| match state {
            State::Free(bells) => (
                State::Held {
                    holder: newcomer(contender),
                    takeover: None,
                },
                Ok(Claimed::Granted(Grant { ticket, bells })),
            ),
            State::Held {
                holder,
                takeover: None,
            } if holder
                .replaceable_by(&contender, now_ns, silence_limit_ns)
                .is_some() =>
            {
                let why = holder.replaceable_by(&contender, now_ns, silence_limit_ns);
                let why = why.unwrap_or(Reason::Restarted);
                let until_ns = now_ns.saturating_add(wait_ns);
                let old = holder.contender.connection.clone();
                let takeover = Takeover {
                    newcomer: newcomer(contender),
                    until_ns,
                };
                let claimed = Claimed::Replacing { ticket, old, why };
                (
                    State::Held {
                        holder,
                        takeover: Some(takeover),
                    },
                    Ok(claimed),
                )
            }
            other => {
                let refusal = other.refusal(&contender);
                (other, Err(refusal))
            }
        })
    }

    /// The contender holding `ticket` asks, at `now_ns`, whether its takeover is through.
    pub(crate) fn replace(
        &mut self,
        ticket: Ticket,
        now_ns: i64,
    ) -> Result<Replace<B>, ClaimError> {
        let waited = self.takeover_wait;
        self.step(|state| match state {
            State::HandingOver { newcomer, bells } if newcomer.ticket == ticket => (
                State::Held {
                    holder: newcomer,
                    takeover: None,
                },
                Ok(Replace::Granted(Grant { ticket, bells })),
            ),
            State::Held {
                holder,
                takeover: Some(takeover),
            } if takeover.newcomer.ticket == ticket => {
                if now_ns < takeover.until_ns {
                    let until_ns = takeover.until_ns;
                    let state = State::Held {
                        holder,
                        takeover: Some(takeover),
                    };
                    return (state, Ok(Replace::Waiting { until_ns }));
                }
                let error = ClaimError::TakeoverTimedOut {
                    holder: holder.contender.name.clone(),
                    waited,
                };
                let state = State::Held {
                    holder,
                    takeover: None,
                };
                (state, Err(error))
            }
            State::Vacant => (State::Vacant, Err(ClaimError::Broken)),
            other => (other, Err(ClaimError::NotWaiting)),
        })
    }

    /// The holder of `grant` gives the slot back. If a takeover waits, the slot passes to it
    /// ([`Released::HandedOver`]: wake it); otherwise it is free. A grant that does not hold the
    /// slot (a caller's mistake) is handed back untouched.
    pub(crate) fn release(&mut self, grant: Grant<B>) -> Result<Released, Grant<B>> {
        self.step(|state| match state {
            State::Held { holder, takeover } if holder.ticket == grant.ticket => match takeover {
                None => (State::Free(grant.bells), Ok(Released::Free)),
                Some(takeover) => (
                    State::HandingOver {
                        newcomer: takeover.newcomer,
                        bells: grant.bells,
                    },
                    Ok(Released::HandedOver),
                ),
            },
            other => (other, Err(grant)),
        })
    }

    /// The contender holding `ticket` gives up waiting (its task was cancelled). A slot already
    /// handed over to it is free again, with the doorbells. Anything else is left as it is.
    pub(crate) fn withdraw(&mut self, ticket: Ticket) {
        self.step(|state| match state {
            State::Held {
                holder,
                takeover: Some(takeover),
            } if takeover.newcomer.ticket == ticket => (
                State::Held {
                    holder,
                    takeover: None,
                },
                (),
            ),
            State::HandingOver { newcomer, bells } if newcomer.ticket == ticket => {
                (State::Free(bells), ())
            }
            other => (other, ()),
        });
    }

    /// The session holding `ticket` heard from its operator at `now_ns` (a packet of any kind).
    /// Anything but the holder's ticket changes nothing.
    pub(crate) fn heard(&mut self, ticket: Ticket, now_ns: i64) {
        if let State::Held { holder, .. } = &mut self.state
            && holder.ticket == ticket
        {
            holder.heard_ns = holder.heard_ns.max(now_ns);
        }
    }

    /// Moves the state out, computes the next one and puts it back.
    fn step<R>(&mut self, transition: impl FnOnce(State<B, C>) -> (State<B, C>, R)) -> R {
        let (next, out) = transition(std::mem::replace(&mut self.state, State::Vacant));
        self.state = next;
        out
    }
}

impl<B, C> State<B, C> {
    /// Why `contender` cannot have the slot in this state (held, or being handed over).
    fn refusal(&self, contender: &Contender<C>) -> ClaimError {
        let (holder, taking_over) = match self {
            State::Held { holder, takeover } => (holder, takeover.is_some()),
            State::HandingOver { newcomer, .. } => (newcomer, true),
            State::Free(_) | State::Vacant => return ClaimError::Broken,
        };
        let name = holder.contender.name.clone();
        if taking_over && holder.same_certificate(contender) {
            ClaimError::TakeoverPending { holder: name }
        } else {
            ClaimError::Busy { holder: name }
        }
    }
}

impl<C> Holder<C> {
    /// Whether, and why, `contender` may take the slot over from this holder at `now_ns`.
    fn replaceable_by(
        &self,
        contender: &Contender<C>,
        now_ns: i64,
        silence_limit_ns: i64,
    ) -> Option<Reason> {
        let silent_ns = now_ns.saturating_sub(self.heard_ns);
        if self.same_certificate(contender) {
            Some(Reason::Restarted)
        } else if silent_ns >= silence_limit_ns {
            let silent = Duration::from_nanos(silent_ns.unsigned_abs());
            Some(Reason::Silent { silent })
        } else {
            None
        }
    }

    /// Whether `contender` presented this holder's certificate (exact DER; none matches none).
    fn same_certificate(&self, contender: &Contender<C>) -> bool {
        contender.certificate.is_some() && contender.certificate == self.contender.certificate
    }
}

fn nanos(d: Duration) -> i64 {
    i64::try_from(d.as_nanos()).unwrap_or(i64::MAX)
}

#[cfg(test)]
mod tests;
