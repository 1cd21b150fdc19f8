//! A seeded, pure link model (delay, jitter, loss, duplicate, reorder, rate) and, in the binary,
//! the UDP shim that drives it in real time. The model reads no clock: time is passed in.
