//! A small HTTP/1.1 server for the live view: GET and HEAD only, one request per
//! connection (`Connection: close`), request heads parsed by `httparse` (already in the
//! tree through zenoh's WebSocket link). Enough for a page on loopback that polls a few
//! endpoints; bounded: at most [`MAX_CONNECTIONS`] at once, request heads of at most
//! [`MAX_HEAD`] bytes, [`READ_TIMEOUT`] to send one.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;

/// Connections served at once; more wait to be accepted.
pub const MAX_CONNECTIONS: usize = 32;
/// Largest request head, bytes.
pub const MAX_HEAD: usize = 16 * 1024;
/// Time a client has to send its request head.
pub const READ_TIMEOUT: Duration = Duration::from_secs(10);

/// A response: status, content type, extra headers and body.
#[derive(Clone, Debug)]
pub struct Response {
    /// HTTP status code.
    pub status: u16,
    /// `Content-Type`.
    pub content_type: &'static str,
    /// Further headers, e.g. `X-Map-Version`.
    pub headers: Vec<(&'static str, String)>,
    /// The body.
    pub body: Arc<Vec<u8>>,
}

impl Response {
    /// 200 with `body`.
    pub fn ok(content_type: &'static str, body: impl Into<Arc<Vec<u8>>>) -> Self {
        Self {
            status: 200,
            content_type,
            headers: Vec::new(),
            body: body.into(),
        }
    }

    /// An error status with a one-line text body.
    pub fn error(status: u16, text: &str) -> Self {
        Self {
            status,
            content_type: "text/plain; charset=utf-8",
            headers: Vec::new(),
            body: Arc::new(format!("{text}\n").into_bytes()),
        }
    }
}

/// Answers requests by path (query string included) until `stop` completes.
pub async fn serve(
    listener: TcpListener,
    handler: Arc<dyn Fn(&str) -> Response + Send + Sync>,
    stop: impl Future<Output = ()>,
) {
    let slots = Arc::new(Semaphore::new(MAX_CONNECTIONS));
    tokio::pin!(stop);
    loop {
        let Ok(permit) = slots.clone().acquire_owned().await else {
            return;
        };
        let stream = tokio::select! {
            _ = &mut stop => return,
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => stream,
                Err(_) => continue,
            },
        };
        let handler = handler.clone();
        tokio::spawn(async move {
            // A client that goes away mid-answer is no error of ours.
            let _ = answer(stream, handler.as_ref()).await;
            drop(permit);
        });
    }
}

/// Reads one request head and writes the handler's response.
async fn answer(
    mut stream: TcpStream,
    handler: &(dyn Fn(&str) -> Response + Send + Sync),
) -> std::io::Result<()> {
    let mut buf = vec![0u8; MAX_HEAD];
    let mut len = 0;
    let head = loop {
        let n = match tokio::time::timeout(READ_TIMEOUT, stream.read(&mut buf[len..])).await {
            Ok(r) => r?,
            Err(_) => return Ok(()),
        };
        if n == 0 {
            return Ok(());
        }
        len += n;
        let mut headers = [httparse::EMPTY_HEADER; 32];
        let mut req = httparse::Request::new(&mut headers);
        match req.parse(&buf[..len]) {
            Ok(httparse::Status::Complete(_)) => {
                break (req.method.map(str::to_owned), req.path.map(str::to_owned))
            }
            Ok(httparse::Status::Partial) if len < buf.len() => continue,
            Ok(httparse::Status::Partial) => {
                return write(
                    &mut stream,
                    &Response::error(431, "request head too large"),
                    true,
                )
                .await
            }
            Err(_) => return write(&mut stream, &Response::error(400, "bad request"), true).await,
        }
    };
    match head {
        (Some(m), Some(path)) if m == "GET" || m == "HEAD" => {
            write(&mut stream, &handler(&path), m == "GET").await
        }
        _ => {
            write(
                &mut stream,
                &Response::error(405, "only GET and HEAD"),
                true,
            )
            .await
        }
    }
}

async fn write(stream: &mut TcpStream, r: &Response, with_body: bool) -> std::io::Result<()> {
    let reason = match r.status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "",
    };
    let mut head = format!(
        "HTTP/1.1 {} {reason}\r\nContent-Type: {}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nConnection: close\r\n",
        r.status,
        r.content_type,
        r.body.len()
    );
    for (name, value) in &r.headers {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    head.push_str("\r\n");
    stream.write_all(head.as_bytes()).await?;
    if with_body {
        stream.write_all(&r.body).await?;
    }
    stream.shutdown().await
}
