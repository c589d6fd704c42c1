//! The CLI's exit statuses, for farm schedulers and scripts that decide whether to retry:
//!
//! | status | meaning |
//! | --- | --- |
//! | 0 | rendered and written (warnings, if any, were printed) |
//! | 2 | the scene, the settings or the output cannot work: retrying will not help |
//! | 3 | a transient failure (the server unreachable or busy, its memory budget full, a disk error): a retry may succeed |
//! | 128 + N | ended by signal N (130 for SIGINT, 143 for SIGTERM), as the shell reports it |

use std::io::ErrorKind;

use crate::remote::ServerError;

/// Retrying will not help.
pub const BAD_INPUT: i32 = 2;
/// A retry may succeed.
pub const TRANSIENT: i32 = 3;

/// The exit status for a failed run: transient for server, transport and disk failures
/// that can pass, bad input for everything else (a scene that does not read, settings the
/// server refuses, an output that cannot be named).
pub fn code_of(e: &anyhow::Error) -> i32 {
    for cause in e.chain() {
        if let Some(s) = cause.downcast_ref::<ServerError>() {
            return match s.code {
                tonic::Code::Unavailable
                | tonic::Code::DeadlineExceeded
                | tonic::Code::Aborted
                | tonic::Code::Cancelled
                | tonic::Code::ResourceExhausted
                | tonic::Code::Internal
                | tonic::Code::Unknown => TRANSIENT,
                _ => BAD_INPUT,
            };
        }
        if cause.downcast_ref::<tonic::transport::Error>().is_some() {
            return TRANSIENT;
        }
        if let Some(io) = cause.downcast_ref::<std::io::Error>() {
            let permanent =
                matches!(io.kind(), ErrorKind::NotFound | ErrorKind::PermissionDenied | ErrorKind::InvalidData | ErrorKind::InvalidInput);
            return if permanent { BAD_INPUT } else { TRANSIENT };
        }
    }
    BAD_INPUT
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn server_codes_map_to_retry_or_not() {
        let server = |code| anyhow::Error::from(ServerError { code, message: "x".into() }).context("rendering");
        assert_eq!(code_of(&server(tonic::Code::InvalidArgument)), BAD_INPUT);
        assert_eq!(code_of(&server(tonic::Code::FailedPrecondition)), BAD_INPUT);
        assert_eq!(code_of(&server(tonic::Code::Unavailable)), TRANSIENT);
        assert_eq!(code_of(&server(tonic::Code::ResourceExhausted)), TRANSIENT);
        let io = |kind| anyhow::Error::from(std::io::Error::new(kind, "x")).context("writing");
        assert_eq!(code_of(&io(ErrorKind::NotFound)), BAD_INPUT, "a scene file that is not there");
        assert_eq!(code_of(&io(ErrorKind::StorageFull)), TRANSIENT, "a full disk");
        assert_eq!(code_of(&anyhow::anyhow!("bad.usda: parse error")), BAD_INPUT);
    }
}
