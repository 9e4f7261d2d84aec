//! The live view answers only requests whose `Host` names it by address or as `localhost`,
//! which defeats DNS rebinding: a page on another site whose name the attacker points at
//! 127.0.0.1 makes the browser send that name as `Host`, and is refused here, so it cannot
//! read the camera images or the map. A user reaching the view from another machine types
//! its address (an IP literal), which passes; a host name other than `localhost` (and its
//! subdomains, which resolve to loopback by RFC 6761) is refused with 421.

use axum::extract::Request;
use axum::http::{header, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

/// Whether a `Host` header value is one the view answers (module doc): an IPv4 or bracketed
/// IPv6 literal, or `localhost` / `*.localhost`, each with an optional port.
pub fn allowed_host(host: &str) -> bool {
    let name = match host.strip_prefix('[') {
        // `[v6]` or `[v6]:port`.
        Some(rest) => {
            let Some((address, after)) = rest.split_once(']') else {
                return false;
            };
            let port_ok = after.is_empty()
                || after
                    .strip_prefix(':')
                    .is_some_and(|p| p.parse::<u16>().is_ok());
            return port_ok && address.parse::<std::net::Ipv6Addr>().is_ok();
        }
        None => match host.rsplit_once(':') {
            Some((name, port)) if port.parse::<u16>().is_ok() => name,
            Some(_) => return false,
            None => host,
        },
    };
    let name = name.to_ascii_lowercase();
    name.parse::<std::net::Ipv4Addr>().is_ok()
        || name == "localhost"
        || name.ends_with(".localhost")
}

/// Middleware: refuses (421 Misdirected Request) a request without a `Host` the view
/// answers ([`allowed_host`]).
pub async fn check_host(request: Request, next: Next) -> Response {
    let host = request
        .headers()
        .get(header::HOST)
        .and_then(|h| h.to_str().ok());
    match host {
        Some(h) if allowed_host(h) => next.run(request).await,
        _ => (
            StatusCode::MISDIRECTED_REQUEST,
            "the live view answers only its address or localhost as Host",
        )
            .into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::allowed_host;

    #[test]
    fn addresses_and_localhost_pass_and_other_names_do_not() {
        for ok in [
            "127.0.0.1:8090",
            "127.0.0.1",
            "192.168.4.2:8090",
            "[::1]:8090",
            "[::1]",
            "localhost:8090",
            "LOCALHOST",
            "view.localhost:1",
        ] {
            assert!(allowed_host(ok), "{ok}");
        }
        for refused in [
            "attacker.example:8090",
            "127.0.0.1.nip.io",
            "localhost.attacker.example",
            "[::1",
            "[::1]x",
            "[::1]:99999",
            "127.0.0.1:port",
            "",
            ":8090",
            "[not-v6]:1",
        ] {
            assert!(!allowed_host(refused), "{refused}");
        }
    }
}
