//! Telerobot daemon: robot bridges, the real-time loop stepping the telerobot node, QUIC server.
//! No estimation logic of its own: that lives in `mmt`'s telerobot node.
