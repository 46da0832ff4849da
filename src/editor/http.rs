//! The HTTP/1.1 of `kb edit`, server side: one request's head parsed by `httparse` (the
//! request line and headers, with caps on their sizes), its `Content-Length` body, and one
//! response written. No chunked bodies, no keep-alive: every response closes its connection.
//! Reading from sockets (timeouts, the connection cap) is `editor::conn`'s.

use std::io::{self, Write};

/// The largest request head (request line and headers), bytes.
pub(crate) const MAX_HEAD: usize = 16 * 1024;
/// The most header lines.
pub(crate) const MAX_HEADERS: usize = 64;
/// The largest body, bytes (a ruleset is at most 4 MiB; the draft's edits are small).
pub(crate) const MAX_BODY: usize = 8 * 1024 * 1024;

/// One request.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Request {
    /// `GET`, `POST`, ...
    pub method: String,
    /// The path, without the query.
    pub path: String,
    /// The query's `key=value` pairs, percent-decoded, in order.
    pub query: Vec<(String, String)>,
    /// Header names lower-cased, values trimmed, in order.
    pub headers: Vec<(String, String)>,
    /// The body (empty without `Content-Length`).
    pub body: Vec<u8>,
}

impl Request {
    /// The first header of this (lower-case) name.
    pub(crate) fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// The first query value of this key.
    pub(crate) fn query(&self, key: &str) -> Option<&str> {
        self.query
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
}

/// Why a request was not read: the status to answer with and a message.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct BadRequest {
    /// 400, 408, 411, 413, 431, 501, 503, ...
    pub status: u16,
    /// What was wrong.
    pub message: String,
}

pub(crate) fn bad(status: u16, message: impl Into<String>) -> BadRequest {
    BadRequest {
        status,
        message: message.into(),
    }
}

/// `%xx` and `+` decoded.
pub(crate) fn percent_decode(s: &str) -> Result<String, BadRequest> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'%' => {
                let hex = s
                    .get(i + 1..i + 3)
                    .and_then(|h| u8::from_str_radix(h, 16).ok())
                    .ok_or_else(|| bad(400, "a bad percent escape in the query"))?;
                out.push(hex);
                i += 3;
            }
            b'+' => {
                out.push(b' ');
                i += 1;
            }
            c => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out).map_err(|_| bad(400, "the query is not UTF-8"))
}

/// A complete request head at the start of `buf`: the request (its body still empty), where
/// its body starts and how long it is. `Ok(None)` while the head is incomplete (and within
/// [`MAX_HEAD`]).
pub(crate) fn parse_head(buf: &[u8]) -> Result<Option<(Request, usize, usize)>, BadRequest> {
    let mut slots = [httparse::EMPTY_HEADER; MAX_HEADERS];
    let mut parsed = httparse::Request::new(&mut slots);
    let head_len = match parsed.parse(buf) {
        Ok(httparse::Status::Complete(n)) => n,
        Ok(httparse::Status::Partial) if buf.len() >= MAX_HEAD => {
            return Err(bad(431, format!("a request head over {MAX_HEAD} bytes")))
        }
        Ok(httparse::Status::Partial) => return Ok(None),
        Err(httparse::Error::TooManyHeaders) => {
            return Err(bad(431, format!("more than {MAX_HEADERS} headers")))
        }
        Err(httparse::Error::Version) => return Err(bad(505, "not HTTP/1.1")),
        Err(e) => return Err(bad(400, format!("a malformed request: {e}"))),
    };
    if head_len > MAX_HEAD {
        return Err(bad(431, format!("a request head over {MAX_HEAD} bytes")));
    }
    let (Some(method), Some(target)) = (parsed.method, parsed.path) else {
        return Err(bad(400, "a malformed request line"));
    };
    if method.is_empty() || !method.bytes().all(|c| c.is_ascii_uppercase()) {
        return Err(bad(400, "a malformed method"));
    }
    if !target.starts_with('/') {
        return Err(bad(400, "the request target is not a path"));
    }
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let path = percent_decode(path)?;
    let mut q = Vec::new();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        q.push((percent_decode(k)?, percent_decode(v)?));
    }
    let mut headers = Vec::with_capacity(parsed.headers.len());
    for h in parsed.headers.iter() {
        let value =
            std::str::from_utf8(h.value).map_err(|_| bad(400, "a header value is not UTF-8"))?;
        headers.push((h.name.to_ascii_lowercase(), value.trim().to_string()));
    }
    let req = Request {
        method: method.to_string(),
        path,
        query: q,
        headers,
        body: Vec::new(),
    };
    let len = body_length(&req)?;
    Ok(Some((req, head_len, len)))
}

/// The body's length: its one `Content-Length` (at most [`MAX_BODY`]); 0 without one, except
/// for a POST.
fn body_length(req: &Request) -> Result<usize, BadRequest> {
    if req.header("transfer-encoding").is_some() {
        return Err(bad(501, "chunked or encoded bodies are not accepted"));
    }
    let mut lengths = req.headers.iter().filter(|(k, _)| k == "content-length");
    let (first, second) = (lengths.next(), lengths.next());
    if second.is_some() {
        return Err(bad(400, "more than one Content-Length"));
    }
    let Some((_, len)) = first else {
        if req.method == "POST" {
            return Err(bad(411, "a POST needs a Content-Length"));
        }
        return Ok(0);
    };
    if len.is_empty() || !len.bytes().all(|c| c.is_ascii_digit()) {
        return Err(bad(400, "a malformed Content-Length"));
    }
    match len.parse::<usize>() {
        Ok(n) if n <= MAX_BODY => Ok(n),
        _ => Err(bad(413, format!("a body over {MAX_BODY} bytes"))),
    }
}

/// Reads one whole request from `r` (a test's bytes; the server reads through `editor::conn`).
#[cfg(test)]
pub(crate) fn read_request(mut r: impl std::io::Read) -> Result<Request, BadRequest> {
    let mut buf = Vec::new();
    r.read_to_end(&mut buf)
        .map_err(|e| bad(400, format!("reading the request: {e}")))?;
    let Some((mut req, start, len)) = parse_head(&buf)? else {
        return Err(bad(400, "the connection closed before the request ended"));
    };
    let body = buf
        .get(start..start + len)
        .ok_or_else(|| bad(400, "the connection closed before the body ended"))?;
    req.body = body.to_vec();
    Ok(req)
}

/// One response.
#[derive(Clone, Debug)]
pub(crate) struct Response {
    /// The status code.
    pub status: u16,
    /// The `Content-Type`.
    pub content_type: &'static str,
    /// The body.
    pub body: Vec<u8>,
}

impl Response {
    /// A JSON response.
    pub(crate) fn json(status: u16, value: &serde_json::Value) -> Response {
        Response {
            status,
            content_type: "application/json",
            body: serde_json::to_vec(value).unwrap_or_default(),
        }
    }

    /// A JSON `{"error": message}` with this status.
    pub(crate) fn error(status: u16, message: &str) -> Response {
        Response::json(status, &serde_json::json!({ "error": message }))
    }
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        408 => "Request Timeout",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        409 => "Conflict",
        411 => "Length Required",
        413 => "Payload Too Large",
        415 => "Unsupported Media Type",
        422 => "Unprocessable Content",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        501 => "Not Implemented",
        503 => "Service Unavailable",
        505 => "HTTP Version Not Supported",
        _ => "Status",
    }
}

/// Writes `resp` with headers that keep the page to itself: no caching, no sniffing, no
/// referrer (the token is in the page's URL), scripts and styles from this server only.
pub(crate) fn write_response(mut w: impl Write, resp: &Response) -> io::Result<()> {
    let head = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n\
         X-Content-Type-Options: nosniff\r\nReferrer-Policy: no-referrer\r\nX-Frame-Options: DENY\r\n\
         Content-Security-Policy: default-src 'self'; img-src 'self' data: blob:; connect-src 'self'; frame-ancestors 'none'\r\n\
         Connection: close\r\n\r\n",
        resp.status,
        reason(resp.status),
        resp.content_type,
        resp.body.len()
    );
    w.write_all(head.as_bytes())?;
    w.write_all(&resp.body)?;
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_is_read_with_its_query_headers_and_body() {
        let raw = b"POST /api/edit?token=ab%20c&x HTTP/1.1\r\nHost: 127.0.0.1:5\r\nContent-Length: 3\r\n\r\nabc";
        let r = read_request(&raw[..]).unwrap();
        assert_eq!(r.method, "POST");
        assert_eq!(r.path, "/api/edit");
        assert_eq!(r.query("token"), Some("ab c"));
        assert_eq!(r.header("host"), Some("127.0.0.1:5"));
        assert_eq!(r.body, b"abc");
    }

    #[test]
    fn malformed_and_oversized_requests_are_refused() {
        let status = |raw: &[u8]| read_request(raw).unwrap_err().status;
        assert_eq!(status(b"GET / HTTP/2\r\n\r\n"), 505);
        assert_eq!(status(b"GET  / HTTP/1.1\r\n\r\n"), 400);
        assert_eq!(status(b"GET http://x/ HTTP/1.1\r\n\r\n"), 400);
        assert_eq!(status(b"POST / HTTP/1.1\r\n\r\n"), 411);
        assert_eq!(
            status(b"POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n"),
            501
        );
        assert_eq!(
            status(b"POST / HTTP/1.1\r\nContent-Length: 99999999999\r\n\r\n"),
            413
        );
        let long = format!("GET /{} HTTP/1.1\r\n\r\n", "a".repeat(MAX_HEAD));
        assert_eq!(status(long.as_bytes()), 431);
        let many = format!(
            "GET / HTTP/1.1\r\n{}\r\n",
            "A: b\r\n".repeat(MAX_HEADERS + 1)
        );
        assert_eq!(status(many.as_bytes()), 431);
        assert_eq!(status(b"GET / HTTP/1.1\r\nHost"), 400);
    }
}
