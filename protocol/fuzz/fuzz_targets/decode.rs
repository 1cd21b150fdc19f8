//! Decodes arbitrary bytes as a message of each direction. Decoding must never panic, and
//! whatever it accepts must survive a re-encode and decode unchanged (every accepted float is
//! finite, so `==` is exact).
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::{operator_to_telerobot as o2t, telerobot_to_operator as t2o};

fuzz_target!(|data: &[u8]| {
    if let Ok(msg) = o2t::decode(data) {
        assert_eq!(o2t::decode(&o2t::encode(&msg)).as_ref(), Ok(&msg));
    }
    if let Ok(msg) = t2o::decode(data) {
        assert_eq!(t2o::decode(&t2o::encode(&msg)).as_ref(), Ok(&msg));
    }
});
