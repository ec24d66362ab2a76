//! # firelink-fwcdev: the /dev/fw* twin, preloaded into any program
//!
//! `libfirelink_fwcdev.so`, loaded with `LD_PRELOAD` and pointed at a twin
//! server by `FIRELINK_FW_CDEV=SOCKET` (`firelink emulate --fw-cdev
//! SOCKET`; `firelink fw-run` sets up both), makes the emulated boards
//! appear to an unmodified program as Linux firewire-cdev devices:
//!
//! - `open`, `open64`, `openat`, `openat64`, `__open_2`, `__open64_2`,
//!   `__openat_2`, `__openat64_2` of `/dev/fw<digits>` connect to the
//!   server instead: the fd returned is one end of a `SOCK_SEQPACKET`
//!   socket on which the server sends the device's events, one per packet,
//!   so `read` returns exactly one event and `poll`, `select` and `epoll`
//!   work natively (the library does not touch them). A second, private
//!   socket per fd carries the ioctls.
//! - `opendir("/dev")` + `readdir`/`readdir64` list the twin's `fw<N>`
//!   after the real entries (libraw1394 finds its devices that way).
//! - `ioctl` on a twin fd: GET_INFO, SEND_REQUEST,
//!   SEND_BROADCAST_REQUEST, INITIATE_BUS_RESET, GET_CYCLE_TIMER(2) and
//!   GET_SPEED are forwarded; any other number fails with ENOTTY, as the
//!   kernel's does for what it does not implement. The kernel's argument
//!   checks (EINVAL, EIO, EACCES, EFAULT) are made here before anything is
//!   sent.
//! - SEND_REQUEST and SEND_BROADCAST_REQUEST return as soon as the request
//!   is sent, without waiting for the server, as the kernel's return once
//!   the request is queued: their outcome is the completion event (a
//!   stale generation too: RCODE_GENERATION, as the kernel reports it).
//!   Their synchronous failures are the argument checks above and ENODEV
//!   for a node that left the bus, which the library learns from the
//!   socket: the server shuts a device's control connection down when it
//!   hangs the device up (the send fails with EPIPE), and from then on
//!   every ioctl on that fd fails with ENODEV at once. The other ioctls
//!   wait for the server's one reply.
//! - `close` of a twin fd closes both sockets.
//!
//! Everything else, and every other path and fd, goes to the next
//! definition (`dlsym(RTLD_NEXT)`), untouched. Without `FIRELINK_FW_CDEV`
//! the library passes everything through.
//!
//! ## Why Rust with fixed arguments, not a C interposer
//! Stable Rust cannot *define* a C variadic function, and `open` and
//! `ioctl` are variadic. On the two ABIs this library is built for, x86-64
//! System V and AArch64 Linux (AAPCS64 as Linux uses it), a variadic
//! integer or pointer argument travels in the same register as a named one
//! at the same position, so a definition with a fixed third argument
//! (`mode_t`, or the ioctl's pointer) receives exactly what the caller
//! passed (and reads a meaningless register, harmlessly, when the caller
//! passed none). Calling the next definition goes through a variadic
//! function pointer, which stable Rust supports. This keeps the twin in
//! one language with its server and lets it use the same checked codecs
//! (`firelink_wire::fw_cdev`) rather than a second, hand-kept C copy of
//! the structures. Other targets (where that argument passing differs,
//! e.g. Apple's AArch64) are refused at compile time.
//!
//! What cannot be interposed: programs that make system calls without
//! glibc (statically linked, or Rust's rustix with its raw backend),
//! setuid programs (the loader ignores `LD_PRELOAD`), and `dup` of a twin
//! fd (the copy is a plain socket without ioctls).
#![allow(unsafe_code)]

#[cfg(not(all(
    target_os = "linux",
    any(target_arch = "x86_64", target_arch = "aarch64")
)))]
compile_error!(
    "the fixed-argument interposers are valid on x86-64 and AArch64 Linux only (see the crate docs)"
);

use std::collections::BTreeMap;
use std::ffi::{CStr, c_char, c_int, c_ulong, c_void};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use firelink_wire::fw_cdev::{
    self, GetInfoArgs, Ioctl, SendRequestArgs, TwinReply, TwinRequest, errno,
};
use libc::{dirent64, mode_t};

/// The environment variable naming the twin's socket.
const SOCKET_ENV: &CStr = c"FIRELINK_FW_CDEV";

// ---- the next definitions ----

type OpenFn = unsafe extern "C" fn(*const c_char, c_int, ...) -> c_int;
type OpenatFn = unsafe extern "C" fn(c_int, *const c_char, c_int, ...) -> c_int;
type Open2Fn = unsafe extern "C" fn(*const c_char, c_int) -> c_int;
type Openat2Fn = unsafe extern "C" fn(c_int, *const c_char, c_int) -> c_int;
type IoctlFn = unsafe extern "C" fn(c_int, c_ulong, ...) -> c_int;
type CloseFn = unsafe extern "C" fn(c_int) -> c_int;
type OpendirFn = unsafe extern "C" fn(*const c_char) -> *mut libc::DIR;
type ReaddirFn = unsafe extern "C" fn(*mut libc::DIR) -> *mut dirent64;
type ClosedirFn = unsafe extern "C" fn(*mut libc::DIR) -> c_int;

/// The next definition of `name` (a NUL-terminated symbol name), looked up
/// once.
fn next(cache: &'static OnceLock<usize>, name: &CStr) -> usize {
    *cache.get_or_init(|| {
        // SAFETY: dlsym with RTLD_NEXT and a valid C string.
        unsafe { libc::dlsym(libc::RTLD_NEXT, name.as_ptr()) as usize }
    })
}

macro_rules! next_fn {
    ($name:ident, $sym:literal, $ty:ty) => {
        fn $name() -> Option<$ty> {
            static CACHE: OnceLock<usize> = OnceLock::new();
            let p = next(&CACHE, $sym);
            // SAFETY: a non-null address dlsym gave for this symbol, whose
            // C type is `$ty`.
            (p != 0).then(|| unsafe { std::mem::transmute::<usize, $ty>(p) })
        }
    };
}

next_fn!(next_open, c"open", OpenFn);
next_fn!(next_open64, c"open64", OpenFn);
next_fn!(next_openat, c"openat", OpenatFn);
next_fn!(next_openat64, c"openat64", OpenatFn);
next_fn!(next_open_2, c"__open_2", Open2Fn);
next_fn!(next_open64_2, c"__open64_2", Open2Fn);
next_fn!(next_openat_2, c"__openat_2", Openat2Fn);
next_fn!(next_openat64_2, c"__openat64_2", Openat2Fn);
next_fn!(next_ioctl, c"ioctl", IoctlFn);
next_fn!(next_close, c"close", CloseFn);
next_fn!(next_opendir, c"opendir", OpendirFn);
next_fn!(next_readdir, c"readdir", ReaddirFn);
next_fn!(next_readdir64, c"readdir64", ReaddirFn);
next_fn!(next_closedir, c"closedir", ClosedirFn);

fn set_errno(e: c_int) {
    // SAFETY: glibc's thread-local errno.
    unsafe { *libc::__errno_location() = e };
}

fn no_symbol() -> c_int {
    set_errno(libc::ENOSYS);
    -1
}

// ---- the twin's fds ----

/// One open twin device: the private control socket, the node's speed
/// code (the kernel's length check depends on it), whether the node is
/// known to have left the bus, and behind a lock (so that one ioctl's
/// request and reply are not interleaved with another's) the buffer its
/// messages are written and read in, made once at open rather than at
/// every ioctl.
struct Device {
    control: c_int,
    speed: u8,
    gone: AtomicBool,
    io: Mutex<Vec<u8>>,
}

impl Device {
    /// ENODEV once the node is known to be gone (`e` is then noted).
    fn note(&self, e: c_int) -> c_int {
        if e == libc::ENODEV {
            self.gone.store(true, Ordering::Relaxed);
        }
        e
    }
}

/// Bytes of a device's message buffer: the largest request, or the
/// largest reply (a GET_INFO with its ROM).
const DEVICE_BUFFER: usize = fw_cdev::TWIN_MAX_MESSAGE + 4096;

fn devices() -> &'static Mutex<BTreeMap<c_int, Arc<Device>>> {
    static DEVICES: OnceLock<Mutex<BTreeMap<c_int, Arc<Device>>>> = OnceLock::new();
    DEVICES.get_or_init(|| Mutex::new(BTreeMap::new()))
}

fn device_of(fd: c_int) -> Option<Arc<Device>> {
    devices().lock().ok()?.get(&fd).cloned()
}

/// The N of an absolute `/dev/fw<N>` path.
fn device_number(path: *const c_char) -> Option<u32> {
    if path.is_null() {
        return None;
    }
    // SAFETY: the caller passed a C string (open's contract).
    let path = unsafe { CStr::from_ptr(path) }.to_bytes();
    let digits = path.strip_prefix(b"/dev/fw")?;
    if digits.is_empty() || digits.len() > 6 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    std::str::from_utf8(digits).ok()?.parse().ok()
}

/// The twin's socket path, when the program runs under the twin.
fn socket_path() -> Option<&'static CStr> {
    // SAFETY: getenv with a valid C string; the environment outlives us
    // for the purpose (the path is only read during the call).
    let p = unsafe { libc::getenv(SOCKET_ENV.as_ptr()) };
    // SAFETY: getenv returns a C string or null.
    (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) })
}

/// A new connection to the twin server (`cloexec`: SOCK_CLOEXEC).
fn connect(cloexec: bool) -> Result<c_int, c_int> {
    let path = socket_path().ok_or(libc::ENOENT)?;
    let bytes = path.to_bytes();
    // SAFETY: a zeroed sockaddr_un is valid.
    let mut addr: libc::sockaddr_un = unsafe { std::mem::zeroed() };
    addr.sun_family = libc::AF_UNIX as libc::sa_family_t;
    if bytes.len() >= addr.sun_path.len() {
        return Err(libc::ENAMETOOLONG);
    }
    for (d, s) in addr.sun_path.iter_mut().zip(bytes) {
        *d = *s as c_char;
    }
    let flags = libc::SOCK_SEQPACKET | if cloexec { libc::SOCK_CLOEXEC } else { 0 };
    // SAFETY: plain socket call.
    let fd = unsafe { libc::socket(libc::AF_UNIX, flags, 0) };
    if fd < 0 {
        return Err(last_errno());
    }
    // SAFETY: addr is a valid sockaddr_un of the given size.
    let r = unsafe {
        libc::connect(
            fd,
            (&raw const addr).cast(),
            std::mem::size_of::<libc::sockaddr_un>() as libc::socklen_t,
        )
    };
    if r < 0 {
        let e = last_errno();
        close_fd(fd);
        // No server: as if the device were not there.
        return Err(if e == libc::ECONNREFUSED {
            libc::ENOENT
        } else {
            e
        });
    }
    Ok(fd)
}

fn last_errno() -> c_int {
    std::io::Error::last_os_error()
        .raw_os_error()
        .unwrap_or(libc::EIO)
}

fn close_fd(fd: c_int) {
    if let Some(close) = next_close() {
        // SAFETY: closing a descriptor this library opened.
        unsafe { close(fd) };
    }
}

/// Send the first `n` bytes of `buf` as one message on `fd`.
fn send_message(fd: c_int, buf: &[u8], n: usize) -> Result<(), c_int> {
    let message = buf.get(..n).ok_or(libc::EINVAL)?;
    loop {
        // SAFETY: `message` is initialised memory of its length.
        let sent = unsafe {
            libc::send(
                fd,
                message.as_ptr().cast(),
                message.len(),
                libc::MSG_NOSIGNAL,
            )
        };
        if sent >= 0 {
            return Ok(());
        }
        let e = last_errno();
        if e != libc::EINTR {
            return Err(gone(e));
        }
    }
}

/// Send one twin request on `fd` and wait for its reply; `buf` holds the
/// request, then the reply. Returns the reply's length.
fn round_trip(fd: c_int, request: &TwinRequest<'_>, buf: &mut [u8]) -> Result<usize, c_int> {
    let n = request.emit(buf).map_err(|_| libc::EINVAL)?;
    send_message(fd, buf, n)?;
    loop {
        // SAFETY: buf is writable for its length.
        let got = unsafe { libc::recv(fd, buf.as_mut_ptr().cast(), buf.len(), 0) };
        if got < 0 && last_errno() == libc::EINTR {
            continue;
        }
        if got <= 0 {
            return Err(libc::ENODEV);
        }
        return Ok(got as usize);
    }
}

/// A server that went away is a device that went away.
fn gone(e: c_int) -> c_int {
    if matches!(
        e,
        libc::EPIPE | libc::ECONNRESET | libc::ENOTCONN | libc::ECONNREFUSED
    ) {
        libc::ENODEV
    } else {
        e
    }
}

/// Open /dev/fw`n` through the twin: the event socket's fd.
fn open_twin(n: u32, flags: c_int) -> c_int {
    match open_twin_inner(n, flags) {
        Ok(fd) => fd,
        Err(e) => {
            set_errno(e);
            -1
        }
    }
}

fn open_twin_inner(n: u32, flags: c_int) -> Result<c_int, c_int> {
    let event = connect(flags & libc::O_CLOEXEC != 0)?;
    let mut buf = [0u8; 64];
    let opened = round_trip(event, &TwinRequest::Open { device: n }, &mut buf)
        .and_then(|len| reply(&buf[..len]).map(|r| r.value));
    let connection = match opened {
        Ok(c) => c,
        Err(e) => {
            close_fd(event);
            // A device that is not there is a path that is not there.
            return Err(if e == libc::ENODEV { libc::ENOENT } else { e });
        }
    };
    let control = match connect(true) {
        Ok(fd) => fd,
        Err(e) => {
            close_fd(event);
            return Err(e);
        }
    };
    let attached = round_trip(control, &TwinRequest::Attach { connection }, &mut buf)
        .and_then(|len| reply(&buf[..len]).map(|r| r.value));
    let speed = match attached {
        Ok(speed) => u8::try_from(speed).unwrap_or(0),
        Err(e) => {
            close_fd(event);
            close_fd(control);
            return Err(e);
        }
    };
    if flags & libc::O_NONBLOCK != 0 {
        // SAFETY: fcntl on our own descriptor.
        unsafe {
            let f = libc::fcntl(event, libc::F_GETFL);
            libc::fcntl(event, libc::F_SETFL, f | libc::O_NONBLOCK);
        }
    }
    if let Ok(mut d) = devices().lock() {
        d.insert(
            event,
            Arc::new(Device {
                control,
                speed,
                gone: AtomicBool::new(false),
                io: Mutex::new(vec![0u8; DEVICE_BUFFER]),
            }),
        );
    }
    Ok(event)
}

/// A reply's value, or its errno.
fn reply(b: &[u8]) -> Result<TwinReply<'_>, c_int> {
    let r = TwinReply::parse(b).map_err(|_| libc::EIO)?;
    if r.errno != 0 {
        return Err(r.errno);
    }
    Ok(r)
}

// ---- ioctl ----

/// Copy `len` bytes from the caller's `ptr` (EFAULT for null).
fn read_arg(ptr: *const c_void, len: usize) -> Result<Vec<u8>, c_int> {
    let mut v = vec![0u8; len];
    copy_arg(ptr, &mut v)?;
    Ok(v)
}

/// Fill `out` from the caller's `ptr` (EFAULT for null), without
/// allocating.
fn copy_arg(ptr: *const c_void, out: &mut [u8]) -> Result<(), c_int> {
    if out.is_empty() {
        return Ok(());
    }
    if ptr.is_null() {
        return Err(errno::EFAULT);
    }
    // SAFETY: the caller's ioctl argument is readable for its size (the
    // kernel's contract; a bad pointer faults as the kernel's EFAULT would
    // not, which is the one difference).
    unsafe { std::ptr::copy_nonoverlapping(ptr.cast::<u8>(), out.as_mut_ptr(), out.len()) };
    Ok(())
}

/// Copy `bytes` to the caller's `ptr` (EFAULT for null).
fn write_arg(ptr: *mut c_void, bytes: &[u8]) -> Result<(), c_int> {
    if bytes.is_empty() {
        return Ok(());
    }
    if ptr.is_null() {
        return Err(errno::EFAULT);
    }
    // SAFETY: as read_arg: the caller's buffer is writable for its size.
    unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), ptr.cast::<u8>(), bytes.len()) };
    Ok(())
}

fn twin_ioctl(device: &Device, request: c_ulong, arg: *mut c_void) -> Result<c_int, c_int> {
    let ioctl = Ioctl::from_request(request).ok_or(errno::ENOTTY)?;
    // The kernel refuses every ioctl of a shut-down device first.
    if device.gone.load(Ordering::Relaxed) {
        return Err(errno::ENODEV);
    }
    twin_ioctl_on(device, ioctl, arg).map_err(|e| device.note(e))
}

fn twin_ioctl_on(device: &Device, ioctl: Ioctl, arg: *mut c_void) -> Result<c_int, c_int> {
    let mut buf = device.io.lock().map_err(|_| libc::EIO)?;
    let buf = buf.as_mut_slice();
    match ioctl {
        Ioctl::GetInfo => {
            let mut a = GetInfoArgs::parse(&read_arg(arg, fw_cdev::GET_INFO_LEN)?)
                .map_err(|_| errno::EFAULT)?;
            let len = round_trip(
                device.control,
                &TwinRequest::GetInfo {
                    version: a.version,
                    rom_length: if a.rom != 0 { a.rom_length } else { 0 },
                    bus_reset_closure: a.bus_reset_closure,
                },
                buf,
            )?;
            let r = reply(&buf[..len])?;
            let (card, rom_length, record, rom) =
                fw_cdev::split_info_payload(r.payload).map_err(|_| libc::EIO)?;
            if a.rom != 0 {
                write_arg(a.rom as *mut c_void, rom)?;
            }
            if a.bus_reset != 0 {
                write_arg(a.bus_reset as *mut c_void, record)?;
            }
            a.version = r.value as u32;
            a.rom_length = rom_length;
            a.card = card;
            let mut out = [0u8; fw_cdev::GET_INFO_LEN];
            a.emit(&mut out).map_err(|_| libc::EIO)?;
            write_arg(arg, &out)?;
            Ok(0)
        }
        Ioctl::SendRequest | Ioctl::SendBroadcastRequest => {
            let broadcast = ioctl == Ioctl::SendBroadcastRequest;
            let mut raw = [0u8; fw_cdev::SEND_REQUEST_LEN];
            copy_arg(arg, &mut raw)?;
            let a = SendRequestArgs::parse(&raw).map_err(|_| errno::EFAULT)?;
            a.check(broadcast, device.speed)?;
            // The payload goes straight into the message. The kernel copies
            // it only when `data` is set (a read may pass none, as
            // libraw1394's asynchronous reads do).
            let at = fw_cdev::SEND_REQUEST_PAYLOAD_AT;
            let payload = buf.get_mut(at..at + a.payload_len()).ok_or(errno::EINVAL)?;
            if a.data == 0 {
                payload.fill(0);
            } else {
                copy_arg(a.data as *const c_void, payload)?;
            }
            let n =
                fw_cdev::emit_send_request_head(broadcast, &a, buf).map_err(|_| errno::EINVAL)?;
            // Queued: the completion event follows on the device's fd.
            send_message(device.control, buf, n)?;
            Ok(0)
        }
        Ioctl::InitiateBusReset => {
            let a = read_arg(arg, fw_cdev::INITIATE_BUS_RESET_LEN)?;
            let kind = u32::from_ne_bytes(a.try_into().map_err(|_| errno::EFAULT)?);
            if kind > 1 {
                return Err(errno::EINVAL);
            }
            let len = round_trip(
                device.control,
                &TwinRequest::InitiateBusReset { short: kind == 1 },
                buf,
            )?;
            reply(&buf[..len])?;
            Ok(0)
        }
        Ioctl::GetCycleTimer | Ioctl::GetCycleTimer2 => {
            let clock = if ioctl == Ioctl::GetCycleTimer2 {
                let a = read_arg(arg, fw_cdev::GET_CYCLE_TIMER2_LEN)?;
                i32::from_ne_bytes(
                    a.get(12..16)
                        .and_then(|c| c.try_into().ok())
                        .ok_or(errno::EFAULT)?,
                )
            } else {
                libc::CLOCK_REALTIME
            };
            let len = round_trip(device.control, &TwinRequest::CycleTimer, buf)?;
            let cycle_timer = reply(&buf[..len])?.value as u32;
            // SAFETY: a zeroed timespec is valid.
            let mut ts: libc::timespec = unsafe { std::mem::zeroed() };
            // SAFETY: clock_gettime writes ts.
            if unsafe { libc::clock_gettime(clock, &mut ts) } != 0 {
                return Err(errno::EINVAL);
            }
            let mut out = Vec::with_capacity(24);
            if ioctl == Ioctl::GetCycleTimer2 {
                out.extend_from_slice(&(ts.tv_sec as i64).to_ne_bytes());
                out.extend_from_slice(&(ts.tv_nsec as i32).to_ne_bytes());
                out.extend_from_slice(&clock.to_ne_bytes());
                out.extend_from_slice(&cycle_timer.to_ne_bytes());
                out.extend_from_slice(&[0; 4]);
            } else {
                let us = ts.tv_sec as u64 * 1_000_000 + ts.tv_nsec as u64 / 1000;
                out.extend_from_slice(&us.to_ne_bytes());
                out.extend_from_slice(&cycle_timer.to_ne_bytes());
                out.extend_from_slice(&[0; 4]);
            }
            write_arg(arg, &out)?;
            Ok(0)
        }
        Ioctl::GetSpeed => {
            let len = round_trip(device.control, &TwinRequest::GetSpeed, buf)?;
            Ok(reply(&buf[..len])?.value as c_int)
        }
    }
}

// ---- the interposed entry points ----

/// Defines one member of the open family: a `/dev/fw<N>` path goes to the
/// twin (when the program runs under one), anything else to the next
/// definition with the caller's arguments unchanged. `$arg: $ty => $pass`
/// lists the parameters after the path's and flags' and how each is passed
/// on (the variadic `mode` travels as the `int` the caller promoted it to).
macro_rules! interpose_open {
    (
        $(#[$doc:meta])*
        $name:ident, $next:ident,
        ($($before:ident: $before_ty:ty),*),
        ($($after:ident: $after_ty:ty => $pass:expr),*)
    ) => {
        $(#[$doc])*
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn $name(
            $($before: $before_ty,)*
            path: *const c_char,
            flags: c_int
            $(, $after: $after_ty)*
        ) -> c_int {
            if let (Some(n), Some(_)) = (device_number(path), socket_path()) {
                return open_twin(n, flags);
            }
            match $next() {
                // SAFETY: forwarding the caller's arguments.
                Some(f) => unsafe { f($($before,)* path, flags $(, $pass)*) },
                None => no_symbol(),
            }
        }
    };
}

interpose_open!(
    /// `open(2)`: `/dev/fw<N>` through the twin, anything else passed on.
    ///
    /// # Safety
    /// As `open(2)`: `path` a C string.
    open, next_open, (), (mode: mode_t => mode as c_int)
);
interpose_open!(
    /// `open64`: as [`open`].
    ///
    /// # Safety
    /// As `open(2)`.
    open64, next_open64, (), (mode: mode_t => mode as c_int)
);
interpose_open!(
    /// `openat`: an absolute `/dev/fw<N>` through the twin.
    ///
    /// # Safety
    /// As `openat(2)`.
    openat, next_openat, (dirfd: c_int), (mode: mode_t => mode as c_int)
);
interpose_open!(
    /// `openat64`: as [`openat`].
    ///
    /// # Safety
    /// As `openat(2)`.
    openat64, next_openat64, (dirfd: c_int), (mode: mode_t => mode as c_int)
);
interpose_open!(
    /// `__open_2` (what `open` becomes under `_FORTIFY_SOURCE`).
    ///
    /// # Safety
    /// As `open(2)`.
    __open_2, next_open_2, (), ()
);
interpose_open!(
    /// `__open64_2`.
    ///
    /// # Safety
    /// As `open(2)`.
    __open64_2, next_open64_2, (), ()
);
interpose_open!(
    /// `__openat_2`.
    ///
    /// # Safety
    /// As `openat(2)`.
    __openat_2, next_openat_2, (dirfd: c_int), ()
);
interpose_open!(
    /// `__openat64_2`.
    ///
    /// # Safety
    /// As `openat(2)`.
    __openat64_2, next_openat64_2, (dirfd: c_int), ()
);

/// `ioctl`: the twin's fds answered by the twin, any other fd passed on.
///
/// # Safety
/// As `ioctl(2)`: `arg` points to the argument the request number names.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ioctl(fd: c_int, request: c_ulong, arg: *mut c_void) -> c_int {
    if let Some(device) = device_of(fd) {
        return match twin_ioctl(&device, request, arg) {
            Ok(v) => v,
            Err(e) => {
                set_errno(e);
                -1
            }
        };
    }
    match next_ioctl() {
        // SAFETY: forwarding the caller's arguments.
        Some(f) => unsafe { f(fd, request, arg) },
        None => no_symbol(),
    }
}

/// `close`: a twin fd takes its control socket with it.
///
/// # Safety
/// As `close(2)`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn close(fd: c_int) -> c_int {
    let device = devices().lock().ok().and_then(|mut d| d.remove(&fd));
    if let Some(device) = device {
        close_fd(device.control);
    }
    match next_close() {
        // SAFETY: forwarding the caller's argument.
        Some(f) => unsafe { f(fd) },
        None => no_symbol(),
    }
}

// ---- listing /dev ----

/// A listing of /dev in progress: the real entries first, then the twin's.
struct Listing {
    real_done: bool,
    twin: Vec<u32>,
    next: usize,
    /// The entry returned last (valid until the next readdir, as POSIX says).
    entry: Box<dirent64>,
}

fn listings() -> &'static Mutex<BTreeMap<usize, Listing>> {
    static LISTINGS: OnceLock<Mutex<BTreeMap<usize, Listing>>> = OnceLock::new();
    LISTINGS.get_or_init(|| Mutex::new(BTreeMap::new()))
}

/// The twin's device numbers, asked of the server.
fn twin_devices() -> Vec<u32> {
    let Ok(fd) = connect(true) else {
        return Vec::new();
    };
    let mut buf = vec![0u8; 4096];
    let list = round_trip(fd, &TwinRequest::List, &mut buf)
        .ok()
        .and_then(|len| {
            reply(&buf[..len]).ok().map(|r| {
                r.payload
                    .chunks_exact(4)
                    .filter_map(|c| c.try_into().ok().map(u32::from_le_bytes))
                    .collect()
            })
        })
        .unwrap_or_default();
    close_fd(fd);
    list
}

fn is_dev(path: *const c_char) -> bool {
    if path.is_null() {
        return false;
    }
    // SAFETY: opendir's argument is a C string.
    let p = unsafe { CStr::from_ptr(path) }.to_bytes();
    p == b"/dev" || p == b"/dev/"
}

/// `opendir`: a listing of /dev is followed so the twin's devices join it.
///
/// # Safety
/// As `opendir(3)`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn opendir(path: *const c_char) -> *mut libc::DIR {
    let Some(f) = next_opendir() else {
        set_errno(libc::ENOSYS);
        return std::ptr::null_mut();
    };
    // SAFETY: forwarding the caller's argument.
    let dir = unsafe { f(path) };
    if !dir.is_null() && is_dev(path) && socket_path().is_some() {
        let twin = twin_devices();
        if let Ok(mut l) = listings().lock() {
            l.insert(
                dir as usize,
                Listing {
                    real_done: false,
                    twin,
                    next: 0,
                    // SAFETY: a zeroed dirent64 is valid.
                    entry: Box::new(unsafe { std::mem::zeroed() }),
                },
            );
        }
    }
    dir
}

fn readdir_with(dir: *mut libc::DIR, real: Option<ReaddirFn>) -> *mut dirent64 {
    let Some(real) = real else {
        set_errno(libc::ENOSYS);
        return std::ptr::null_mut();
    };
    let followed = listings()
        .lock()
        .ok()
        .is_some_and(|l| l.contains_key(&(dir as usize)));
    if !followed {
        // SAFETY: forwarding the caller's argument.
        return unsafe { real(dir) };
    }
    let Ok(mut l) = listings().lock() else {
        return std::ptr::null_mut();
    };
    let Some(listing) = l.get_mut(&(dir as usize)) else {
        return std::ptr::null_mut();
    };
    if !listing.real_done {
        // SAFETY: forwarding the caller's argument.
        let e = unsafe { real(dir) };
        if !e.is_null() {
            return e;
        }
        listing.real_done = true;
    }
    let Some(&n) = listing.twin.get(listing.next) else {
        return std::ptr::null_mut();
    };
    listing.next += 1;
    let name = format!("fw{n}");
    let entry = &mut *listing.entry;
    entry.d_ino = 0x4657_0000 + u64::from(n);
    entry.d_off = listing.next as i64;
    entry.d_reclen = std::mem::size_of::<dirent64>() as u16;
    entry.d_type = libc::DT_CHR;
    entry.d_name = [0; 256];
    for (d, s) in entry.d_name.iter_mut().zip(name.bytes()) {
        *d = s as c_char;
    }
    entry as *mut dirent64
}

/// `readdir`: the real entries, then (for /dev) the twin's `fw<N>`. On the
/// 64-bit ABIs `struct dirent` and `struct dirent64` are the same.
///
/// # Safety
/// As `readdir(3)`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn readdir(dir: *mut libc::DIR) -> *mut dirent64 {
    readdir_with(dir, next_readdir())
}

/// `readdir64`: as [`readdir`].
///
/// # Safety
/// As `readdir(3)`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn readdir64(dir: *mut libc::DIR) -> *mut dirent64 {
    readdir_with(dir, next_readdir64())
}

/// `closedir`: the listing is forgotten.
///
/// # Safety
/// As `closedir(3)`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn closedir(dir: *mut libc::DIR) -> c_int {
    if let Ok(mut l) = listings().lock() {
        l.remove(&(dir as usize));
    }
    match next_closedir() {
        // SAFETY: forwarding the caller's argument.
        Some(f) => unsafe { f(dir) },
        None => no_symbol(),
    }
}
