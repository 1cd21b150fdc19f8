//! Operator app: haptic devices, the safety layer, the haptic loop stepping the operator node,
//! QUIC client and the `demo` command. No rendering logic of its own: that is `mmt`'s operator node.
