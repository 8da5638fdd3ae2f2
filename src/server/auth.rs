//! Admin-plane authentication: `Authorization: Bearer <token>`, compared in constant time.
//! The token is never logged (the request log records method, route and status only).

use super::error::{ApiError, Kind};
use super::state::SharedState;
use axum::extract::{Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use subtle::ConstantTimeEq;

/// Whether `header_value` carries `token` as a bearer credential.
pub fn bearer_matches(header_value: Option<&[u8]>, token: &str) -> bool {
    let Some(value) = header_value else {
        return false;
    };
    let Some(presented) = value
        .strip_prefix(b"Bearer ")
        .or_else(|| value.strip_prefix(b"bearer "))
    else {
        return false;
    };
    // Lengths are not secret; the bytes are compared without early exit.
    presented.len() == token.len() && bool::from(presented.ct_eq(token.as_bytes()))
}

pub async fn require_token(
    State(state): State<SharedState>,
    request: Request,
    next: Next,
) -> Response {
    let token = state.config.admin_token.as_deref().unwrap_or_default();
    let presented = request
        .headers()
        .get(header::AUTHORIZATION)
        .map(|v| v.as_bytes());
    if token.is_empty() || !bearer_matches(presented, token) {
        return ApiError::new(
            Kind::Unauthorized,
            "missing or wrong bearer token (Authorization: Bearer <token>)",
        )
        .into_response();
    }
    next.run(request).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bearer_comparison() {
        let token = "0123456789abcdef";
        assert!(bearer_matches(Some(b"Bearer 0123456789abcdef"), token));
        assert!(!bearer_matches(Some(b"Bearer 0123456789abcdeX"), token));
        assert!(!bearer_matches(Some(b"Bearer 0123456789abcde"), token));
        assert!(!bearer_matches(Some(b"Basic 0123456789abcdef"), token));
        assert!(!bearer_matches(None, token));
    }
}
