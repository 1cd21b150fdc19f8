//! Decodes arbitrary bytes as a message of each direction and as each side's first
//! control-stream message (the version handshake). Decoding must never panic; whatever it
//! accepts must survive a re-encode and decode unchanged (every accepted float is finite, so `==`
//! is exact); and the handshake must agree with the decoders: a `Hello` it accepts is the decoded
//! `Hello` of this version, a `Welcome` it accepts passes `check_welcome`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::handshake::{accept_hello, accept_welcome, check_welcome};
use protocol::{PROTOCOL_VERSION, operator_to_telerobot as o2t, telerobot_to_operator as t2o};

fuzz_target!(|data: &[u8]| {
    let operator = o2t::decode(data);
    if let Ok(msg) = &operator {
        assert_eq!(o2t::decode(&o2t::encode(msg)).as_ref(), Ok(msg));
    }
    let telerobot = t2o::decode(data);
    if let Ok(msg) = &telerobot {
        assert_eq!(t2o::decode(&t2o::encode(msg)).as_ref(), Ok(msg));
    }
    if let Ok(hello) = accept_hello(data) {
        assert_eq!(hello.version, PROTOCOL_VERSION);
        assert_eq!(operator, Ok(o2t::Message::Hello(hello)));
    }
    if let Ok(welcome) = accept_welcome(data) {
        assert_eq!(check_welcome(&welcome), Ok(()));
        assert_eq!(telerobot, Ok(t2o::Message::Welcome(welcome)));
    }
});
