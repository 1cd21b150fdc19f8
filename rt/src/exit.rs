//! What a binary prints when it stops on an error: one line, the error and its causes.

use std::error::Error;

/// `err`'s message followed by each cause's, `: `-separated, leaving out a cause whose message
/// the line already holds. Errors that both print their source and return it from
/// [`Error::source`] (thiserror's `{source}` fields, `#[from]` with `{0}`) are so printed once:
/// anyhow's `{:#}` gave `Is a directory (os error 21): Is a directory (os error 21)`.
pub fn message(err: &(dyn Error + 'static)) -> String {
    let mut line = err.to_string();
    let mut source = err.source();
    while let Some(cause) = source {
        let text = cause.to_string();
        if !text.is_empty() && !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        source = cause.source();
    }
    line
}

#[cfg(test)]
mod tests {
    use super::message;

    #[derive(Debug)]
    struct Wrapped {
        shows_cause: bool,
        cause: std::io::Error,
    }

    impl std::fmt::Display for Wrapped {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            if self.shows_cause {
                write!(f, "cannot read scene file /tmp: {}", self.cause)
            } else {
                write!(f, "cannot read scene file /tmp")
            }
        }
    }

    impl std::error::Error for Wrapped {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.cause)
        }
    }

    fn wrapped(shows_cause: bool) -> Wrapped {
        Wrapped {
            shows_cause,
            cause: std::io::Error::other("Is a directory (os error 21)"),
        }
    }

    #[test]
    fn a_cause_is_printed_once_whether_or_not_the_error_shows_it() {
        let once = "cannot read scene file /tmp: Is a directory (os error 21)";
        assert_eq!(message(&wrapped(true)), once);
        assert_eq!(message(&wrapped(false)), once);
        // With no cause, the message alone.
        assert_eq!(
            message(&std::io::Error::other("no such file")),
            "no such file"
        );
    }
}
