//! Wire protocol between the operator app and the telerobot daemon.
//!
//! What it is: the message types by direction, the one `encode`/`decode` pair (bincode 2, pinned),
//! the version handshake and the session state machine (heartbeat, RTT, clock offset).
//! What it is not: no sockets, no clocks, no threads; it depends on no other crate of ours.
