//! Socket addresses as the daemons' command lines take them: the telerobot's `--listen`, the
//! operator's `--connect`. Each kind's error shows an IPv4 and an IPv6 example of its own.

use std::net::SocketAddr;

/// Examples of an address to listen on: every interface, IPv4 or IPv6.
pub const LISTEN_EXAMPLES: &str = "0.0.0.0:4433 or [::]:4433";

/// Examples of an address to connect to: a telerobot on the LAN, or this machine over IPv6.
pub const CONNECT_EXAMPLES: &str = "192.168.1.20:4433 or [::1]:4433";

/// A socket address that is not IP:PORT.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("'{text}' is not IP:PORT (e.g. {examples})")]
pub struct AddressError {
    /// What was given.
    pub text: String,
    /// What would have been right ([`LISTEN_EXAMPLES`] or [`CONNECT_EXAMPLES`]).
    pub examples: &'static str,
}

/// An address to listen on, IP:PORT (a `clap` value parser).
pub fn parse_listen_addr(text: &str) -> Result<SocketAddr, AddressError> {
    parse(text, LISTEN_EXAMPLES)
}

/// An address to connect to, IP:PORT (a `clap` value parser).
pub fn parse_connect_addr(text: &str) -> Result<SocketAddr, AddressError> {
    parse(text, CONNECT_EXAMPLES)
}

fn parse(text: &str, examples: &'static str) -> Result<SocketAddr, AddressError> {
    text.parse().map_err(|_| AddressError {
        text: text.to_owned(),
        examples,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ip_and_port_parse_for_both_kinds() {
        for parse in [parse_listen_addr, parse_connect_addr] {
            assert_eq!(
                parse("0.0.0.0:4433"),
                Ok(SocketAddr::from(([0, 0, 0, 0], 4433)))
            );
            assert_eq!(
                parse("[::1]:9"),
                Ok(SocketAddr::from(([0, 0, 0, 0, 0, 0, 0, 1], 9)))
            );
        }
    }

    #[test]
    fn anything_else_is_refused_with_the_kinds_own_examples() {
        assert_eq!(
            parse_listen_addr("4433").unwrap_err().to_string(),
            "'4433' is not IP:PORT (e.g. 0.0.0.0:4433 or [::]:4433)"
        );
        assert_eq!(
            parse_connect_addr("telerobot:4433")
                .unwrap_err()
                .to_string(),
            "'telerobot:4433' is not IP:PORT (e.g. 192.168.1.20:4433 or [::1]:4433)"
        );
        for bad in [
            "",
            "1.2.3.4",
            "1.2.3.4:",
            "1.2.3.4:70000",
            "::1:4433",
            " 1.2.3.4:1",
        ] {
            assert!(parse_listen_addr(bad).is_err(), "{bad:?}");
        }
    }
}
