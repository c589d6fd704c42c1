//! Who is calling: bearer tokens in the `authorization` metadata name tenants. With no tokens
//! configured (loopback, one user) every caller is the tenant [`LOCAL`]. A session belongs
//! to the tenant that created it; to every other tenant it does not exist.

use std::sync::Arc;

use tonic::{Request, Status};

/// The tenant of every caller when the server has no tokens.
pub const LOCAL: &str = "local";

/// The caller's tenant, put in each request's extensions by [`Auth::check`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tenant(pub Arc<str>);

/// The configured tokens: each names one tenant.
#[derive(Clone, Debug, Default)]
pub struct Auth {
    /// (tenant, token); empty: no authentication.
    tokens: Vec<(Arc<str>, Vec<u8>)>,
}

impl Auth {
    /// No tokens: every caller is [`LOCAL`].
    pub fn open() -> Self {
        Auth::default()
    }

    /// True when callers must present a token.
    pub fn required(&self) -> bool {
        !self.tokens.is_empty()
    }

    /// Reads a token file: one tenant per line, `TOKEN` or `NAME TOKEN`; `#` starts a comment.
    /// A tenant without a name is called after its line ("line 3"), so logs never hold tokens.
    pub fn from_file_contents(text: &str) -> Result<Self, String> {
        let mut tokens = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split_whitespace().collect();
            let (name, token) = match fields.as_slice() {
                [token] => (format!("line {}", i + 1), *token),
                [name, token] => (name.to_string(), *token),
                _ => return Err(format!("line {}: expected TOKEN or NAME TOKEN", i + 1)),
            };
            if token.len() < 16 {
                return Err(format!("line {}: a token needs at least 16 characters (use 32 random bytes, hex)", i + 1));
            }
            if tokens.iter().any(|(_, t): &(Arc<str>, Vec<u8>)| t == token.as_bytes()) {
                return Err(format!("line {}: this token is already on an earlier line", i + 1));
            }
            tokens.push((Arc::from(name), token.as_bytes().to_vec()));
        }
        if tokens.is_empty() {
            return Err("the token file holds no tokens".into());
        }
        Ok(Auth { tokens })
    }

    /// The tenant a bearer token names, comparing every token in constant time.
    fn tenant_of(&self, presented: &[u8]) -> Option<Arc<str>> {
        let mut found = None;
        for (tenant, token) in &self.tokens {
            if constant_time_eq(token, presented) {
                found = Some(Arc::clone(tenant));
            }
        }
        found
    }

    /// The interceptor: puts the caller's [`Tenant`] in the request, or refuses it with
    /// `UNAUTHENTICATED`.
    #[allow(clippy::result_large_err)]
    pub fn check(&self, mut req: Request<()>) -> Result<Request<()>, Status> {
        let tenant = if self.required() {
            let header = req
                .metadata()
                .get("authorization")
                .ok_or_else(|| Status::unauthenticated("this server needs a token: send 'authorization: Bearer TOKEN' metadata"))?;
            let presented = header
                .as_bytes()
                .strip_prefix(b"Bearer ")
                .ok_or_else(|| Status::unauthenticated("the authorization metadata must read 'Bearer TOKEN'"))?;
            self.tenant_of(presented).ok_or_else(|| Status::unauthenticated("the token is not known to this server"))?
        } else {
            Arc::from(LOCAL)
        };
        req.extensions_mut().insert(Tenant(tenant));
        Ok(req)
    }
}

/// Equality whose time depends only on the lengths, so a wrong token's timing says nothing
/// about how much of it was right.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The tenant the interceptor found for `req` ([`LOCAL`] for in-process calls that skip it).
pub fn tenant_of<T>(req: &Request<T>) -> Tenant {
    req.extensions().get::<Tenant>().cloned().unwrap_or_else(|| Tenant(Arc::from(LOCAL)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILE: &str = "# studio tokens\nalice 0123456789abcdef0123\n\nfedcba9876543210fedc  # the farm\n";

    fn with_token(token: &str) -> Request<()> {
        let mut r = Request::new(());
        r.metadata_mut().insert("authorization", format!("Bearer {token}").parse().unwrap());
        r
    }

    #[test]
    fn tokens_name_tenants() {
        let auth = Auth::from_file_contents(FILE).unwrap();
        let r = auth.check(with_token("0123456789abcdef0123")).unwrap();
        assert_eq!(tenant_of(&r), Tenant(Arc::from("alice")));
        let r = auth.check(with_token("fedcba9876543210fedc")).unwrap();
        assert_eq!(tenant_of(&r), Tenant(Arc::from("line 4")));
    }

    #[test]
    fn wrong_missing_and_malformed_tokens_are_unauthenticated() {
        let auth = Auth::from_file_contents(FILE).unwrap();
        for req in [with_token("0123456789abcdef0124"), with_token(""), Request::new(())] {
            assert_eq!(auth.check(req).unwrap_err().code(), tonic::Code::Unauthenticated);
        }
        let mut basic = Request::new(());
        basic.metadata_mut().insert("authorization", "Basic 0123456789abcdef0123".parse().unwrap());
        assert_eq!(auth.check(basic).unwrap_err().code(), tonic::Code::Unauthenticated);
    }

    #[test]
    fn without_tokens_everyone_is_local() {
        let r = Auth::open().check(Request::new(())).unwrap();
        assert_eq!(tenant_of(&r), Tenant(Arc::from(LOCAL)));
    }

    #[test]
    fn bad_token_files_are_refused_by_line() {
        assert!(Auth::from_file_contents("short").unwrap_err().contains("line 1"));
        assert!(Auth::from_file_contents("a b c").unwrap_err().contains("line 1"));
        assert!(Auth::from_file_contents("# nothing\n").is_err());
        let dup = "0123456789abcdef0123\nbob 0123456789abcdef0123\n";
        assert!(Auth::from_file_contents(dup).unwrap_err().contains("line 2"));
    }
}
