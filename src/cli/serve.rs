//! `reflectance serve` and `reflectance healthcheck`.

use super::CliResult;
use crate::server::config::ServeArgs;
use clap::Args;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::Duration;

pub fn run(args: ServeArgs) -> CliResult {
    let token = std::env::var("REFLECTANCE_ADMIN_TOKEN").ok();
    let config = args.into_config(token)?;
    crate::server::run(config)
}

#[derive(Args, Debug)]
pub struct HealthcheckArgs {
    /// Address of the data plane.
    #[arg(
        long,
        env = "REFLECTANCE_HEALTHCHECK_ADDR",
        default_value = "127.0.0.1:8080"
    )]
    addr: String,
    /// Path to GET.
    #[arg(long, default_value = "/health/ready")]
    path: String,
    /// Seconds to wait for the answer.
    #[arg(long, default_value_t = 3.0)]
    timeout: f64,
}

/// GET the path over plain HTTP/1.1 (no client library needed in the container).
pub fn healthcheck(args: HealthcheckArgs) -> CliResult {
    let timeout = Duration::from_secs_f64(args.timeout.clamp(0.1, 60.0));
    let addr: SocketAddr = args
        .addr
        .to_socket_addrs()
        .map_err(|e| format!("{}: {e}", args.addr))?
        .next()
        .ok_or_else(|| format!("{}: no address", args.addr))?;
    let mut stream =
        TcpStream::connect_timeout(&addr, timeout).map_err(|e| format!("{addr}: {e}"))?;
    stream
        .set_read_timeout(Some(timeout))
        .and_then(|()| stream.set_write_timeout(Some(timeout)))
        .map_err(|e| e.to_string())?;
    write!(
        stream,
        "GET {} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n",
        args.path
    )
    .map_err(|e| format!("{addr}: {e}"))?;
    let mut head = [0u8; 64];
    let n = stream.read(&mut head).map_err(|e| format!("{addr}: {e}"))?;
    let line = String::from_utf8_lossy(&head[..n]);
    let status = line.split_whitespace().nth(1).unwrap_or_default();
    if status == "200" {
        Ok(())
    } else {
        Err(format!("{addr}{} answered {status:?}", args.path))
    }
}
