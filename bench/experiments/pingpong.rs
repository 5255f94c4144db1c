// Two-process 64-byte TCP ping-pong: `block` (blocking recv), `epoll N` (edge-triggered epoll,
// N µs of spinning on a non-blocking recv first), `spinyield N` (the spin with sched_yield).
// SO_BUSY_POLL=µs sets that option. Standalone (not in the workspace): `rustc -O --edition 2024
// pingpong.rs`, then `./pingpong block`. Used for docs/performance.md, "Transport speed".
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

#[repr(C, packed)]
#[derive(Clone, Copy)]
struct EpollEvent { events: u32, data: u64 }
unsafe extern "C" {
    fn epoll_create1(flags: i32) -> i32;
    fn epoll_ctl(epfd: i32, op: i32, fd: i32, ev: *mut EpollEvent) -> i32;
    fn epoll_wait(epfd: i32, evs: *mut EpollEvent, max: i32, timeout: i32) -> i32;
    fn sched_getcpu() -> i32;
    fn setsockopt(fd: i32, level: i32, name: i32, val: *const i32, len: u32) -> i32;
}
const EPOLLIN: u32 = 1; const EPOLLOUT: u32 = 4; const EPOLLET: u32 = 1 << 31;

struct W { mode: String, ep: i32, spin: Duration, migr: u64, last_cpu: i32 }
impl W {
    fn new(mode: &str, s: &TcpStream, spin_us: u64) -> W {
        let ep = unsafe { epoll_create1(0) };
        let mut ev = EpollEvent { events: EPOLLIN | EPOLLOUT | EPOLLET, data: 1 };
        unsafe { epoll_ctl(ep, 1, s.as_raw_fd(), &mut ev) };
        if mode != "block" { s.set_nonblocking(true).unwrap(); }
        if let Ok(v) = std::env::var("BUSY_POLL") { let v: i32 = v.parse().unwrap(); unsafe { setsockopt(s.as_raw_fd(), 1, 46, &v, 4) }; }
        W { mode: mode.into(), ep, spin: Duration::from_micros(spin_us), migr: 0, last_cpu: -1 }
    }
    fn read(&mut self, s: &mut TcpStream, buf: &mut [u8]) -> usize {
        let r = if self.mode == "block" { s.read(buf).unwrap() } else {
            let start = Instant::now();
            loop {
                match s.read(buf) {
                    Ok(n) => break n,
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                        if start.elapsed() < self.spin {
                            if self.mode == "spinyield" { std::thread::yield_now(); } else { std::hint::spin_loop(); }
                            continue;
                        }
                        let mut evs = [EpollEvent { events: 0, data: 0 }; 8];
                        unsafe { epoll_wait(self.ep, evs.as_mut_ptr(), 8, -1) };
                    }
                    Err(e) => panic!("{e}"),
                }
            }
        };
        let cpu = unsafe { sched_getcpu() };
        if cpu != self.last_cpu { self.migr += 1; self.last_cpu = cpu; }
        r
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mode = args[1].clone();
    let spin: u64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(0);
    if args.len() > 3 && args[3] == "child" {
        let mut s = TcpStream::connect(&args[4]).unwrap();
        s.set_nodelay(true).unwrap();
        let mut w = W::new(&mode, &s, spin);
        let mut buf = [0u8; 64];
        loop {
            let n = w.read(&mut s, &mut buf);
            if n == 0 { eprintln!("child cpu changes {}", w.migr); return; }
            let mut off = 0; while off < n { match s.write(&buf[off..n]) { Ok(k) => off += k, Err(_) => {} } }
        }
    }
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap().to_string();
    let mut child = std::process::Command::new(&args[0]).args([&mode, &spin.to_string(), "child", &addr]).spawn().unwrap();
    let (mut s, _) = l.accept().unwrap();
    s.set_nodelay(true).unwrap();
    let mut w = W::new(&mode, &s, spin);
    let msg = [0xA5u8; 64]; let mut buf = [0u8; 64];
    let n = 20000; let mut ts = Vec::with_capacity(n);
    let t0 = Instant::now();
    for _ in 0..n {
        let t = Instant::now();
        let mut off = 0; while off < 64 { match s.write(&msg[off..]) { Ok(k) => off += k, Err(_) => {} } }
        let mut got = 0; while got < 64 { got += w.read(&mut s, &mut buf[got..]); }
        ts.push(t.elapsed());
    }
    let wall = t0.elapsed();
    drop(s); child.wait().unwrap();
    ts.sort();
    println!("{mode} spin={spin}us p50 {:.1} p90 {:.1} p99 {:.1} us; parent cpu changes {}; wall {:?}", ts[n/2].as_secs_f64()*1e6, ts[n*9/10].as_secs_f64()*1e6, ts[n*99/100].as_secs_f64()*1e6, w.migr, wall);
}
