//! Who may use the console: the holder of the token, from this machine, through a page of the
//! console itself.
//!
//! Every request must carry the session's token (`?token=…`, 128 random bits from the operating
//! system, printed once in the console's URL), name the console's own address as its `Host` (a
//! page on another site that resolves its own name to 127.0.0.1, DNS rebinding, names its own), and,
//! when the browser says where the request comes from (`Origin`, which browsers send with every
//! WebSocket handshake and every cross-site request), come from the console's own origin. Anything
//! else is answered 403 with the reason, and nothing else happens.

use std::fmt;

/// The console's access rule: its token and its address.
#[derive(Clone)]
pub struct Access {
    token: String,
    port: u16,
}

impl fmt::Debug for Access {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The token stays out of logs.
        f.debug_struct("Access").field("port", &self.port).finish()
    }
}

/// Why a request was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// No `token` in the query.
    #[error("refused: this console needs the token in the URL that `host-sim teach` printed")]
    NoToken,
    /// A token, not the session's.
    #[error("refused: wrong token (each `host-sim teach` prints a new one)")]
    WrongToken,
    /// Another `Host` than the console's address.
    #[error("refused: host {0:?} is not this console's address")]
    Host(String),
    /// Another `Origin` than the console's.
    #[error("refused: requests from {0:?} are not this console's")]
    Origin(String),
}

impl Access {
    /// The rule for a console on 127.0.0.1:`port` with a new random token.
    pub fn new(port: u16) -> anyhow::Result<Self> {
        use rand::TryRng;
        let mut bytes = [0u8; 16];
        rand::rngs::SysRng
            .try_fill_bytes(&mut bytes)
            .map_err(|e| anyhow::anyhow!("no random token: {e}"))?;
        Ok(Self::with_token(
            port,
            bytes.iter().map(|b| format!("{b:02x}")).collect(),
        ))
    }

    /// The rule with a given token (tests).
    pub fn with_token(port: u16, token: String) -> Self {
        Self { token, port }
    }

    /// The token.
    pub fn token(&self) -> &str {
        &self.token
    }

    /// The address, `127.0.0.1:PORT`.
    pub fn authority(&self) -> String {
        format!("127.0.0.1:{}", self.port)
    }

    /// The URL to open: `http://127.0.0.1:PORT/?token=…`.
    pub fn url(&self) -> String {
        format!("http://{}/?token={}", self.authority(), self.token)
    }

    /// Checks a request's query, `Host` and `Origin` headers.
    pub fn check(
        &self,
        query: Option<&str>,
        host: Option<&str>,
        origin: Option<&str>,
    ) -> Result<(), Refusal> {
        let hosts = [
            format!("127.0.0.1:{}", self.port),
            format!("localhost:{}", self.port),
        ];
        let host = host.unwrap_or_default();
        if !hosts.iter().any(|h| h == host) {
            return Err(Refusal::Host(host.to_string()));
        }
        if let Some(origin) = origin
            && !hosts.iter().any(|h| origin == format!("http://{h}"))
        {
            return Err(Refusal::Origin(origin.to_string()));
        }
        let given = query
            .unwrap_or_default()
            .split('&')
            .find_map(|pair| pair.strip_prefix("token="))
            .ok_or(Refusal::NoToken)?;
        if equal_in_constant_time(given.as_bytes(), self.token.as_bytes()) {
            Ok(())
        } else {
            Err(Refusal::WrongToken)
        }
    }
}

/// Whether `a == b`, in a time that depends on their lengths only.
fn equal_in_constant_time(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn access() -> Access {
        Access::with_token(4242, "00ff".into())
    }

    #[test]
    fn the_token_from_this_console_s_address_is_let_in() {
        let a = access();
        assert_eq!(a.url(), "http://127.0.0.1:4242/?token=00ff");
        for host in ["127.0.0.1:4242", "localhost:4242"] {
            assert_eq!(a.check(Some("token=00ff"), Some(host), None), Ok(()));
            assert_eq!(
                a.check(
                    Some("x=1&token=00ff"),
                    Some(host),
                    Some("http://127.0.0.1:4242")
                ),
                Ok(())
            );
        }
    }

    #[test]
    fn a_missing_or_wrong_token_is_refused() {
        let a = access();
        let host = Some("127.0.0.1:4242");
        assert_eq!(a.check(None, host, None), Err(Refusal::NoToken));
        assert_eq!(a.check(Some("tok=00ff"), host, None), Err(Refusal::NoToken));
        for wrong in ["token=", "token=00fe", "token=00ff0", "token=00FF"] {
            assert_eq!(
                a.check(Some(wrong), host, None),
                Err(Refusal::WrongToken),
                "{wrong}"
            );
        }
    }

    #[test]
    fn another_host_or_origin_is_refused_even_with_the_token() {
        let a = access();
        let q = Some("token=00ff");
        assert_eq!(
            a.check(q, Some("evil.example:4242"), None),
            Err(Refusal::Host("evil.example:4242".into()))
        );
        assert_eq!(a.check(q, None, None), Err(Refusal::Host(String::new())));
        assert_eq!(
            a.check(q, Some("127.0.0.1:4243"), None),
            Err(Refusal::Host("127.0.0.1:4243".into()))
        );
        for origin in [
            "http://evil.example",
            "http://127.0.0.1:4243",
            "https://127.0.0.1:4242",
            "null",
        ] {
            assert_eq!(
                a.check(q, Some("127.0.0.1:4242"), Some(origin)),
                Err(Refusal::Origin(origin.into())),
                "{origin}"
            );
        }
    }

    #[test]
    fn tokens_are_new_each_time_and_stay_out_of_debug_output() {
        let (a, b) = (Access::new(1).unwrap(), Access::new(1).unwrap());
        assert_eq!(a.token().len(), 32);
        assert_ne!(a.token(), b.token());
        assert!(!format!("{a:?}").contains(a.token()));
    }
}
