// The node's way of reading a 921,600-byte frame, outside the node: `r2e`, `spare`, `spare_reuse`,
// `single` (see the code). Standalone: `rustc -O --edition 2024 image_read.rs`.
// Mimics the node's receive path: non-blocking socket, epoll ET, a 64 KiB first read into a
// reader buffer, then the payload moved to its own Vec and filled by read_to_end on a take.
use std::io::{Read, Write, ErrorKind};
use std::net::{TcpListener, TcpStream};
use std::os::fd::AsRawFd;
use std::sync::mpsc::channel;
use std::time::{Duration, Instant};
#[repr(C, packed)] #[derive(Clone, Copy)] struct Ev { events: u32, data: u64 }
unsafe extern "C" { fn epoll_create1(f: i32) -> i32; fn epoll_ctl(e: i32, op: i32, fd: i32, ev: *mut Ev) -> i32; fn epoll_wait(e: i32, evs: *mut Ev, m: i32, t: i32) -> i32; #[link_name = "recv"] fn libc_recv(fd: i32, b: *mut u8, l: usize, f: i32) -> isize; fn setsockopt(fd: i32, l: i32, n: i32, v: *const i32, len: u32) -> i32; }
const N: usize = 921_608;
fn wait(ep: i32, t: i32) { let mut evs = [Ev { events: 0, data: 0 }; 8]; unsafe { epoll_wait(ep, evs.as_mut_ptr(), 8, t) }; }
fn main() {
    let mode = std::env::args().nth(1).unwrap();
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap();
    let (tx, rx) = channel::<Instant>();
    let m2 = mode.clone();
    std::thread::spawn(move || {
        let (mut s, _) = l.accept().unwrap();
        s.set_nonblocking(true).unwrap();
        let ep = unsafe { epoll_create1(0) };
        let mut ev = Ev { events: 1 | 4 | (1 << 31), data: 1 };
        unsafe { epoll_ctl(ep, 1, s.as_raw_fd(), &mut ev) };
        let mut head = vec![0u8; 65536];
        let mut keep: Vec<u8> = Vec::with_capacity(N);
        loop {
            // first read: up to 64K into head
            let got = loop { match s.read(&mut head) { Ok(0) => return, Ok(n) => break n, Err(e) if e.kind() == ErrorKind::WouldBlock => wait(ep, 20), Err(_) => return } };
            let mut v: Vec<u8> = if m2 == "spare_reuse" { let mut r = std::mem::take(&mut keep); r.clear(); r } else { Vec::with_capacity(N) };
            v.extend_from_slice(&head[..got]);
            while v.len() < N {
                let room = (N - v.len()) as u64;
                if m2.starts_with("spare") {
                    let spare = v.spare_capacity_mut();
                    let n = unsafe { libc_recv(s.as_raw_fd(), spare.as_mut_ptr() as *mut u8, spare.len(), 0) };
                    if n > 0 { unsafe { v.set_len(v.len() + n as usize) }; } else { wait(ep, 20); }
                    continue;
                }
                if m2 == "single" {
                    match s.read(&mut head[..(room as usize).min(65536)]) { Ok(n) => v.extend_from_slice(&head[..n]), Err(e) if e.kind() == ErrorKind::WouldBlock => wait(ep, 20), Err(_) => return }
                    continue;
                }
                match (&mut s).take(room).read_to_end(&mut v) { Ok(_) => {}, Err(e) if e.kind() == ErrorKind::WouldBlock => wait(ep, 20), Err(_) => return }
            }
            std::hint::black_box(&v);
            if m2 == "spare_reuse" { keep = v; }
            tx.send(Instant::now()).unwrap();
        }
    });
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_nodelay(true).unwrap();
    if std::env::var("SNDBUF").is_ok() { let v: i32 = std::env::var("SNDBUF").unwrap().parse().unwrap(); unsafe { setsockopt(s.as_raw_fd(), 1, 7, &v, 4) }; }
    let frame: Vec<u8> = (0..N).map(|i| (i % 251) as u8).collect();
    let mut ts = vec![];
    for _ in 0..500 {
        let t = Instant::now();
        s.write_all(&frame).unwrap();
        let at = loop { match rx.recv_timeout(Duration::from_micros(200)) { Ok(at) => break at, Err(_) => {} } };
        ts.push(at - t);
    }
    ts.sort();
    println!("{mode} sndbuf={:?}: p50 {:?}", std::env::var("SNDBUF").ok(), ts[ts.len() / 2]);
}
