//! Token access control: with a token configured, every RPC must carry
//! `authorization: Bearer TOKEN`, otherwise it is refused with `Unauthenticated`.

use gaitsweep_core::{bearer, AUTH_HEADER};
use tonic::{Request, Status};

/// Checks the bearer token of every request (no token configured: everything passes).
#[derive(Clone)]
pub struct TokenCheck {
    expected: Option<String>,
}

impl TokenCheck {
    /// A check for `token` (`None`: no access control).
    pub fn new(token: Option<&str>) -> Self {
        Self {
            expected: token.map(bearer),
        }
    }
}

/// Whether a presented token equals the expected one, compared in constant time.
pub fn same_token(given: &str, expected: &str) -> bool {
    same(given.as_bytes(), expected.as_bytes())
}

/// Compares without an early exit, so timing does not reveal the token.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

impl tonic::service::Interceptor for TokenCheck {
    fn call(&mut self, req: Request<()>) -> Result<Request<()>, Status> {
        let Some(expected) = &self.expected else {
            return Ok(req);
        };
        match req.metadata().get(AUTH_HEADER) {
            Some(v) if same(v.as_bytes(), expected.as_bytes()) => Ok(req),
            Some(_) => Err(Status::unauthenticated(
                "the access token is wrong: pass the coordinator's --token",
            )),
            None => Err(Status::unauthenticated(
                "an access token is required: pass --token (metadata authorization: Bearer TOKEN)",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tonic::service::Interceptor;

    #[test]
    fn refuses_missing_and_wrong_tokens() {
        let mut c = TokenCheck::new(Some("s3cret"));
        assert_eq!(
            c.call(Request::new(())).unwrap_err().code(),
            tonic::Code::Unauthenticated
        );
        let mut r = Request::new(());
        r.metadata_mut()
            .insert(AUTH_HEADER, "Bearer nope".parse().unwrap());
        assert_eq!(c.call(r).unwrap_err().code(), tonic::Code::Unauthenticated);
        let mut r = Request::new(());
        r.metadata_mut()
            .insert(AUTH_HEADER, "Bearer s3cret".parse().unwrap());
        assert!(c.call(r).is_ok());
        assert!(TokenCheck::new(None).call(Request::new(())).is_ok());
    }
}
