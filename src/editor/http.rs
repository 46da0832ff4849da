//! A small, strict HTTP/1.1 server side: one request read from a connection (request line,
//! headers, a `Content-Length` body) with caps on every size, and one response written. No
//! chunked bodies, no keep-alive: every response closes its connection.

use std::io::{self, BufRead, BufReader, Read, Write};

/// The longest request line or header line, bytes.
pub(crate) const MAX_LINE: usize = 8 * 1024;
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
    /// 400, 411, 413, 431, 501, ...
    pub status: u16,
    /// What was wrong.
    pub message: String,
}

fn bad(status: u16, message: impl Into<String>) -> BadRequest {
    BadRequest {
        status,
        message: message.into(),
    }
}

/// One line (without CRLF) of at most [`MAX_LINE`] bytes.
fn read_line(r: &mut impl BufRead) -> Result<String, BadRequest> {
    let mut buf = Vec::new();
    let n = r
        .take(MAX_LINE as u64 + 1)
        .read_until(b'\n', &mut buf)
        .map_err(|e| bad(400, format!("reading the request: {e}")))?;
    if n == 0 {
        return Err(bad(400, "the connection closed before the request ended"));
    }
    if !buf.ends_with(b"\n") && n <= MAX_LINE {
        return Err(bad(400, "the connection closed before the request ended"));
    }
    if !buf.ends_with(b"\n") {
        return Err(bad(
            431,
            format!("a request line is longer than {MAX_LINE} bytes"),
        ));
    }
    buf.pop();
    if buf.ends_with(b"\r") {
        buf.pop();
    }
    String::from_utf8(buf).map_err(|_| bad(400, "a request line is not UTF-8"))
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

/// Reads one request from `stream`.
pub(crate) fn read_request(stream: impl Read) -> Result<Request, BadRequest> {
    let mut r = BufReader::new(stream);
    let line = read_line(&mut r)?;
    let mut parts = line.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(bad(400, "a malformed request line"));
    };
    if version != "HTTP/1.1" && version != "HTTP/1.0" {
        return Err(bad(505, format!("{version} is not HTTP/1.1")));
    }
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
    let mut headers = Vec::new();
    loop {
        let line = read_line(&mut r)?;
        if line.is_empty() {
            break;
        }
        if headers.len() == MAX_HEADERS {
            return Err(bad(431, format!("more than {MAX_HEADERS} headers")));
        }
        let Some((k, v)) = line.split_once(':') else {
            return Err(bad(400, "a header line without a colon"));
        };
        if k.is_empty() || k.bytes().any(|c| c.is_ascii_whitespace()) {
            return Err(bad(400, "a malformed header name"));
        }
        headers.push((k.to_ascii_lowercase(), v.trim().to_string()));
    }
    let mut req = Request {
        method: method.to_string(),
        path,
        query: q,
        headers,
        body: Vec::new(),
    };
    if req.header("transfer-encoding").is_some() {
        return Err(bad(501, "chunked or encoded bodies are not accepted"));
    }
    let lengths: Vec<&str> = req
        .headers
        .iter()
        .filter(|(k, _)| k == "content-length")
        .map(|(_, v)| v.as_str())
        .collect();
    if lengths.len() > 1 {
        return Err(bad(400, "more than one Content-Length"));
    }
    if let Some(len) = lengths.first() {
        let len: usize = len
            .parse()
            .map_err(|_| bad(400, "a malformed Content-Length"))?;
        if len > MAX_BODY {
            return Err(bad(413, format!("a body over {MAX_BODY} bytes")));
        }
        let mut body = vec![0; len];
        r.read_exact(&mut body)
            .map_err(|e| bad(400, format!("reading the body: {e}")))?;
        req.body = body;
    } else if req.method == "POST" {
        return Err(bad(411, "a POST needs a Content-Length"));
    }
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
        let long = format!("GET /{} HTTP/1.1\r\n\r\n", "a".repeat(MAX_LINE));
        assert_eq!(status(long.as_bytes()), 431);
        let many = format!(
            "GET / HTTP/1.1\r\n{}\r\n",
            "A: b\r\n".repeat(MAX_HEADERS + 1)
        );
        assert_eq!(status(many.as_bytes()), 431);
        assert_eq!(status(b"GET / HTTP/1.1\r\nHost"), 400);
    }
}
