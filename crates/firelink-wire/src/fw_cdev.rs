//! Linux firewire-cdev as bytes: the kernel's ioctl arguments and events
//! (`linux/firewire-cdev.h`), and the twin's own request/reply framing.
//!
//! Two users share these codecs: the `fw` port of the host library (which
//! talks to a real kernel through them) and the /dev/fw* twin (a preloaded
//! library that forwards ioctls to `firelink emulate --fw-cdev`, and the
//! server that answers them). Layouts are those of the 64-bit Linux ABIs
//! (x86-64 and aarch64 agree: natural alignment, `__u64` on 8 bytes), in
//! native byte order for the kernel structures.
//!
//! ## The twin protocol (over one `SOCK_SEQPACKET` unix socket)
//! Every message is one packet; integers are little-endian. A connection's
//! first message says what it is for:
//! - [`TwinRequest::Open`] `{device}`: an *event* connection, one per open
//!   /dev/fwN. The server answers [`TwinReply`] once (errno 0 and the
//!   connection's ID in `value`); from then on it sends only kernel events,
//!   exactly one per packet, each as `read()` returns it.
//! - [`TwinRequest::Attach`] `{connection}`: the *control* connection of
//!   that event connection. The server answers [`TwinReply`] once (errno 0
//!   and the node's speed code in `value`: the library needs it for the
//!   kernel's length check). Then each ioctl is one message on it:
//!   - SEND_REQUEST and SEND_BROADCAST_REQUEST are one-way
//!     ([`TwinRequest::expects_reply`] is false): the kernel only queues
//!     the request and reports its outcome as an event, so the library
//!     makes the kernel's synchronous checks itself, sends the request and
//!     returns; the server sends nothing back on the control connection,
//!     only the one completion event on the event connection. A request
//!     whose node left is refused by the socket itself (the server shuts
//!     the control connection down when it hangs up the device: EPIPE,
//!     which the library reports as ENODEV).
//!   - every other request (GET_INFO, INITIATE_BUS_RESET, GET_CYCLE_TIMER,
//!     GET_SPEED) gets exactly one [`TwinReply`]: an errno (0 for
//!     success), a value, and a payload.
//!
//!   A message the server cannot parse closes the control connection (the
//!   library never sends one; answering it could be taken for the reply
//!   to a later call).
//! - [`TwinRequest::List`]: the device numbers present, as
//!   [`TwinReply`] payload (u32 each); the server then closes.
//!
//! After [`check_len`](SendRequestArgs::parse)-style checks succeed no
//! accessor panics: every parser here reads through `get`.

use crate::{Error, Result};

/// Linux errno values the kernel's firewire-cdev returns (the same on
/// x86-64 and aarch64).
pub mod errno {
    /// I/O error: a request longer than the node's speed allows.
    pub const EIO: i32 = 5;
    /// Bad address (an argument pointer the caller cannot read).
    pub const EFAULT: i32 = 14;
    /// Permission denied: a broadcast below the units space.
    pub const EACCES: i32 = 13;
    /// No such device: the node left the bus.
    pub const ENODEV: i32 = 19;
    /// Invalid argument: a tcode or length the call does not take.
    pub const EINVAL: i32 = 22;
    /// Inappropriate ioctl: a number the device does not implement.
    pub const ENOTTY: i32 = 25;
}

/// The ABI version the kernel reports in GET_INFO (Linux 6.5 on).
pub const KERNEL_ABI_VERSION: u32 = 6;
/// The first ABI version whose clients get RESPONSE2 events.
pub const ABI_RESPONSE2: u32 = 6;

/// Event type: a bus reset (`FW_CDEV_EVENT_BUS_RESET`).
pub const EVENT_BUS_RESET: u32 = 0x00;
/// Event type: a response (`FW_CDEV_EVENT_RESPONSE`, clients with ABI < 6).
pub const EVENT_RESPONSE: u32 = 0x01;
/// Event type: a response with time stamps (`FW_CDEV_EVENT_RESPONSE2`, ABI >= 6).
pub const EVENT_RESPONSE2: u32 = 0x0b;

/// Pseudo rcodes of the kernel (`firewire-constants.h`), beside the wire's 0..=7.
pub mod rcode {
    /// The transaction completed.
    pub const COMPLETE: u32 = 0x0;
    /// The node answered with a data error.
    pub const DATA_ERROR: u32 = 0x5;
    /// The node does not take this request type.
    pub const TYPE_ERROR: u32 = 0x6;
    /// The address is not there.
    pub const ADDRESS_ERROR: u32 = 0x7;
    /// Sending failed.
    pub const SEND_ERROR: u32 = 0x10;
    /// No response within the split time-out.
    pub const CANCELLED: u32 = 0x11;
    /// The node stayed busy.
    pub const BUSY: u32 = 0x12;
    /// The request carried a stale bus generation.
    pub const GENERATION: u32 = 0x13;
    /// No acknowledgement: nobody there.
    pub const NO_ACK: u32 = 0x14;
}

/// Lowest offset a broadcast request may write (`CSR_REGISTER_BASE +
/// CSR_CONFIG_ROM_END`): the kernel refuses anything below with EACCES.
pub const BROADCAST_MIN_OFFSET: u64 = 0xFFFF_F000_0800;
/// Largest payload of any request (`init_request`: EIO beyond it).
pub const MAX_REQUEST_LENGTH: u32 = 4096;

/// Size of `struct fw_cdev_event_bus_reset` on the 64-bit ABIs: the 36
/// bytes of the record and 4 bytes of tail padding (`sizeof`, as the
/// kernel copies it).
pub const BUS_RESET_EVENT_LEN: usize = 40;
/// Header of `struct fw_cdev_event_response` (`sizeof`): data at 20.
pub const RESPONSE_HEADER_LEN: usize = 24;
/// Header of `struct fw_cdev_event_response2` (`sizeof`): data at 32.
pub const RESPONSE2_HEADER_LEN: usize = 32;
/// Size of `struct fw_cdev_get_info`.
pub const GET_INFO_LEN: usize = 40;
/// Size of `struct fw_cdev_send_request`.
pub const SEND_REQUEST_LEN: usize = 40;
/// Size of `struct fw_cdev_initiate_bus_reset`.
pub const INITIATE_BUS_RESET_LEN: usize = 4;
/// Size of `struct fw_cdev_get_cycle_timer`.
pub const GET_CYCLE_TIMER_LEN: usize = 16;
/// Size of `struct fw_cdev_get_cycle_timer2`.
pub const GET_CYCLE_TIMER2_LEN: usize = 24;

/// An ioctl number `_IOC(dir, '#', nr, size)` of the generic Linux
/// encoding (x86-64 and aarch64).
pub const fn ioc(dir: u32, nr: u32, size: usize) -> u64 {
    ((dir as u64) << 30) | ((size as u64) << 16) | ((b'#' as u64) << 8) | nr as u64
}
const IOC_WRITE: u32 = 1;
const IOC_READ: u32 = 2;

/// `FW_CDEV_IOC_GET_INFO`.
pub const IOC_GET_INFO: u64 = ioc(IOC_READ | IOC_WRITE, 0x00, GET_INFO_LEN);
/// `FW_CDEV_IOC_SEND_REQUEST`.
pub const IOC_SEND_REQUEST: u64 = ioc(IOC_WRITE, 0x01, SEND_REQUEST_LEN);
/// `FW_CDEV_IOC_INITIATE_BUS_RESET`.
pub const IOC_INITIATE_BUS_RESET: u64 = ioc(IOC_WRITE, 0x05, INITIATE_BUS_RESET_LEN);
/// `FW_CDEV_IOC_GET_CYCLE_TIMER`.
pub const IOC_GET_CYCLE_TIMER: u64 = ioc(IOC_READ, 0x0c, GET_CYCLE_TIMER_LEN);
/// `FW_CDEV_IOC_GET_SPEED`.
pub const IOC_GET_SPEED: u64 = ioc(0, 0x11, 0);
/// `FW_CDEV_IOC_SEND_BROADCAST_REQUEST`.
pub const IOC_SEND_BROADCAST_REQUEST: u64 = ioc(IOC_WRITE, 0x12, SEND_REQUEST_LEN);
/// `FW_CDEV_IOC_GET_CYCLE_TIMER2`.
pub const IOC_GET_CYCLE_TIMER2: u64 = ioc(IOC_READ | IOC_WRITE, 0x14, GET_CYCLE_TIMER2_LEN);

/// The ioctls the twin implements (anything else: ENOTTY).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ioctl {
    /// GET_INFO.
    GetInfo,
    /// SEND_REQUEST.
    SendRequest,
    /// SEND_BROADCAST_REQUEST.
    SendBroadcastRequest,
    /// INITIATE_BUS_RESET.
    InitiateBusReset,
    /// GET_CYCLE_TIMER.
    GetCycleTimer,
    /// GET_CYCLE_TIMER2.
    GetCycleTimer2,
    /// GET_SPEED.
    GetSpeed,
}

impl Ioctl {
    /// The ioctl a request number names, if the twin implements it (the
    /// number must match in type, number, direction and size, as the
    /// kernel's dispatch does).
    pub fn from_request(request: u64) -> Option<Ioctl> {
        // Only the low 32 bits carry the number (glibc takes an unsigned long).
        Some(match request & 0xFFFF_FFFF {
            IOC_GET_INFO => Ioctl::GetInfo,
            IOC_SEND_REQUEST => Ioctl::SendRequest,
            IOC_SEND_BROADCAST_REQUEST => Ioctl::SendBroadcastRequest,
            IOC_INITIATE_BUS_RESET => Ioctl::InitiateBusReset,
            IOC_GET_CYCLE_TIMER => Ioctl::GetCycleTimer,
            IOC_GET_CYCLE_TIMER2 => Ioctl::GetCycleTimer2,
            IOC_GET_SPEED => Ioctl::GetSpeed,
            _ => return None,
        })
    }
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_ne_bytes(b.get(at..at + 4)?.try_into().ok()?))
}
fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_ne_bytes(b.get(at..at + 8)?.try_into().ok()?))
}
fn put(out: &mut [u8], at: usize, bytes: &[u8]) -> Result<()> {
    let available = out.len();
    out.get_mut(at..at + bytes.len())
        .ok_or(Error::BufferTooSmall {
            what: "fw-cdev structure",
            needed: at + bytes.len(),
            available,
        })?
        .copy_from_slice(bytes);
    Ok(())
}
fn truncated(what: &'static str, needed: usize, available: usize) -> Error {
    Error::Truncated {
        what,
        needed,
        available,
    }
}

/// `struct fw_cdev_get_info` as the caller fills it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GetInfoArgs {
    /// The client's ABI version.
    pub version: u32,
    /// Room at `rom` in bytes.
    pub rom_length: u32,
    /// Where to copy the config ROM (0: not asked).
    pub rom: u64,
    /// Where to copy the bus-reset record (0: not asked).
    pub bus_reset: u64,
    /// Closure of later BUS_RESET events.
    pub bus_reset_closure: u64,
    /// Card index (output).
    pub card: u32,
}

impl GetInfoArgs {
    /// Parse the 40 bytes of the argument.
    ///
    /// # Errors
    /// [`Error::Truncated`] when shorter.
    pub fn parse(b: &[u8]) -> Result<GetInfoArgs> {
        let t = || truncated("fw_cdev_get_info", GET_INFO_LEN, b.len());
        Ok(GetInfoArgs {
            version: u32_at(b, 0).ok_or_else(t)?,
            rom_length: u32_at(b, 4).ok_or_else(t)?,
            rom: u64_at(b, 8).ok_or_else(t)?,
            bus_reset: u64_at(b, 16).ok_or_else(t)?,
            bus_reset_closure: u64_at(b, 24).ok_or_else(t)?,
            card: u32_at(b, 32).ok_or_else(t)?,
        })
    }

    /// Write the 40 bytes of the argument (padding zero).
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, out: &mut [u8]) -> Result<()> {
        put(out, 0, &self.version.to_ne_bytes())?;
        put(out, 4, &self.rom_length.to_ne_bytes())?;
        put(out, 8, &self.rom.to_ne_bytes())?;
        put(out, 16, &self.bus_reset.to_ne_bytes())?;
        put(out, 24, &self.bus_reset_closure.to_ne_bytes())?;
        put(out, 32, &self.card.to_ne_bytes())?;
        put(out, 36, &[0; 4])
    }
}

/// `struct fw_cdev_send_request`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SendRequestArgs {
    /// Transaction code (0 write quadlet, 1 write block, 4 read quadlet,
    /// 5 read block, locks).
    pub tcode: u32,
    /// Payload bytes (written, or asked for).
    pub length: u32,
    /// 48-bit destination offset.
    pub offset: u64,
    /// Closure returned in the completion event.
    pub closure: u64,
    /// Where the payload is (also read for reads, as the kernel does).
    pub data: u64,
    /// The bus generation the request is meant for.
    pub generation: u32,
}

impl SendRequestArgs {
    /// Parse the 40 bytes of the argument.
    ///
    /// # Errors
    /// [`Error::Truncated`] when shorter.
    pub fn parse(b: &[u8]) -> Result<SendRequestArgs> {
        let t = || truncated("fw_cdev_send_request", SEND_REQUEST_LEN, b.len());
        Ok(SendRequestArgs {
            tcode: u32_at(b, 0).ok_or_else(t)?,
            length: u32_at(b, 4).ok_or_else(t)?,
            offset: u64_at(b, 8).ok_or_else(t)?,
            closure: u64_at(b, 16).ok_or_else(t)?,
            data: u64_at(b, 24).ok_or_else(t)?,
            generation: u32_at(b, 32).ok_or_else(t)?,
        })
    }

    /// Write the 40 bytes of the argument.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, out: &mut [u8]) -> Result<()> {
        put(out, 0, &self.tcode.to_ne_bytes())?;
        put(out, 4, &self.length.to_ne_bytes())?;
        put(out, 8, &self.offset.to_ne_bytes())?;
        put(out, 16, &self.closure.to_ne_bytes())?;
        put(out, 24, &self.data.to_ne_bytes())?;
        put(out, 32, &self.generation.to_ne_bytes())?;
        put(out, 36, &[0; 4])
    }

    /// The kernel's refusals, in its order (`ioctl_send_request`,
    /// `ioctl_send_broadcast_request`, `init_request`): a tcode the call
    /// does not take (EINVAL), a broadcast below the units space
    /// (EACCES), a payload over 4096 bytes or over what `speed` carries
    /// (512 << speed; EIO), a quadlet write shorter than 4 bytes (EINVAL).
    ///
    /// # Errors
    /// The errno the kernel returns.
    pub fn check(&self, broadcast: bool, speed: u8) -> core::result::Result<(), i32> {
        let tcode_ok = if broadcast {
            matches!(self.tcode, 0 | 1)
        } else {
            // Reads, writes and the lock family (extended tcodes 0x11..=0x17
            // the kernel folds into its own numbering).
            matches!(self.tcode, 0 | 1 | 4 | 5 | 0x11..=0x17)
        };
        if !tcode_ok {
            return Err(errno::EINVAL);
        }
        if broadcast && self.offset < BROADCAST_MIN_OFFSET {
            return Err(errno::EACCES);
        }
        let speed = if broadcast { 0 } else { speed.min(5) };
        if self.length > MAX_REQUEST_LENGTH || self.length > 512u32 << speed {
            return Err(errno::EIO);
        }
        if self.tcode == 0 && self.length < 4 {
            return Err(errno::EINVAL);
        }
        Ok(())
    }

    /// Bytes the kernel copies from `data` (every tcode: `length`).
    pub fn payload_len(&self) -> usize {
        self.length as usize
    }
}

/// The bus-reset record (`struct fw_cdev_event_bus_reset` without
/// closure and type).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BusResetRecord {
    /// The fd's node (`0xffc0 | phy`).
    pub node_id: u32,
    /// The PC's own node.
    pub local_node_id: u32,
    /// The bus manager.
    pub bm_node_id: u32,
    /// The isochronous resource manager.
    pub irm_node_id: u32,
    /// The root node.
    pub root_node_id: u32,
    /// The bus generation.
    pub generation: u32,
}

impl BusResetRecord {
    /// Write the event (or GET_INFO's copy of it): [`BUS_RESET_EVENT_LEN`]
    /// bytes with `closure` and type 0.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, closure: u64, out: &mut [u8]) -> Result<usize> {
        put(out, 0, &closure.to_ne_bytes())?;
        put(out, 8, &EVENT_BUS_RESET.to_ne_bytes())?;
        put(out, 12, &self.node_id.to_ne_bytes())?;
        put(out, 16, &self.local_node_id.to_ne_bytes())?;
        put(out, 20, &self.bm_node_id.to_ne_bytes())?;
        put(out, 24, &self.irm_node_id.to_ne_bytes())?;
        put(out, 28, &self.root_node_id.to_ne_bytes())?;
        put(out, 32, &self.generation.to_ne_bytes())?;
        put(out, 36, &[0; 4])?;
        Ok(BUS_RESET_EVENT_LEN)
    }

    /// Parse a bus-reset event: (closure, record).
    ///
    /// # Errors
    /// [`Error::Truncated`] under 36 bytes, [`Error::InvalidValue`] for
    /// another event type.
    pub fn parse(b: &[u8]) -> Result<(u64, BusResetRecord)> {
        let t = || truncated("fw_cdev_event_bus_reset", 36, b.len());
        let kind = u32_at(b, 8).ok_or_else(t)?;
        if kind != EVENT_BUS_RESET {
            return Err(Error::InvalidValue {
                what: "bus reset event type",
                value: kind,
            });
        }
        Ok((
            u64_at(b, 0).ok_or_else(t)?,
            BusResetRecord {
                node_id: u32_at(b, 12).ok_or_else(t)?,
                local_node_id: u32_at(b, 16).ok_or_else(t)?,
                bm_node_id: u32_at(b, 20).ok_or_else(t)?,
                irm_node_id: u32_at(b, 24).ok_or_else(t)?,
                root_node_id: u32_at(b, 28).ok_or_else(t)?,
                generation: u32_at(b, 32).ok_or_else(t)?,
            },
        ))
    }
}

/// The bytes of the response event the kernel queues for a client of ABI
/// `version`: RESPONSE (data at 20) below 6, RESPONSE2 (time stamps at 20
/// and 24, data at 32) from 6. Below 6 the kernel's quirk is kept: the
/// event is always `24 + length` bytes, and for 4 bytes or less the data
/// appears twice (at 20, inside the header, and again at 24). Returns the
/// event's length.
///
/// # Errors
/// [`Error::BufferTooSmall`].
pub fn emit_response(
    version: u32,
    closure: u64,
    rcode: u32,
    data: &[u8],
    stamps: (u32, u32),
    out: &mut [u8],
) -> Result<usize> {
    let length = data.len();
    put(out, 0, &closure.to_ne_bytes())?;
    put(out, 12, &rcode.to_ne_bytes())?;
    put(out, 16, &(length as u32).to_ne_bytes())?;
    if version >= ABI_RESPONSE2 {
        put(out, 8, &EVENT_RESPONSE2.to_ne_bytes())?;
        put(out, 20, &stamps.0.to_ne_bytes())?;
        put(out, 24, &stamps.1.to_ne_bytes())?;
        put(out, 28, &[0; 4])?;
        put(out, RESPONSE2_HEADER_LEN, data)?;
        return Ok(RESPONSE2_HEADER_LEN + length);
    }
    put(out, 8, &EVENT_RESPONSE.to_ne_bytes())?;
    if length <= 4 {
        // The header's own 4 bytes from 20 hold the data (zero-filled),
        // then the second copy.
        let mut inline = [0u8; 4];
        if let Some(d) = inline.get_mut(..length) {
            d.copy_from_slice(data);
        }
        put(out, 20, &inline)?;
        put(out, RESPONSE_HEADER_LEN, data)?;
    } else {
        put(out, 20, data)?;
        // The 4 bytes after the data: what followed it in the kernel's
        // buffer (zero here).
        put(out, 20 + length, &[0; 4])?;
    }
    Ok(RESPONSE_HEADER_LEN + length)
}

/// A response event read back: what a client takes from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResponseEvent<'a> {
    /// The request's closure.
    pub closure: u64,
    /// The rcode (wire or kernel pseudo rcode).
    pub rcode: u32,
    /// The data.
    pub data: &'a [u8],
}

impl<'a> ResponseEvent<'a> {
    /// Parse a RESPONSE or RESPONSE2 event.
    ///
    /// # Errors
    /// [`Error::Truncated`], [`Error::LengthExceedsBuffer`] when the length
    /// field claims more than the event holds, [`Error::InvalidValue`] for
    /// another event type.
    pub fn parse(b: &'a [u8]) -> Result<ResponseEvent<'a>> {
        let t = || truncated("fw_cdev_event_response", 20, b.len());
        let kind = u32_at(b, 8).ok_or_else(t)?;
        let at = match kind {
            EVENT_RESPONSE => 20,
            EVENT_RESPONSE2 => RESPONSE2_HEADER_LEN,
            _ => {
                return Err(Error::InvalidValue {
                    what: "response event type",
                    value: kind,
                });
            }
        };
        let length = u32_at(b, 16).ok_or_else(t)? as usize;
        let data = b
            .get(at..)
            .and_then(|d| d.get(..length))
            .ok_or(Error::LengthExceedsBuffer {
                what: "fw_cdev_event_response",
                declared: length,
                available: b.len().saturating_sub(at),
            })?;
        Ok(ResponseEvent {
            closure: u64_at(b, 0).ok_or_else(t)?,
            rcode: u32_at(b, 12).ok_or_else(t)?,
            data,
        })
    }
}

/// An event's type (the `type` field at 8), if it has one.
pub fn event_type(b: &[u8]) -> Option<u32> {
    u32_at(b, 8)
}

// ---- the twin protocol ----

const OP_OPEN: u32 = 1;
const OP_ATTACH: u32 = 2;
const OP_LIST: u32 = 3;
const OP_GET_INFO: u32 = 10;
const OP_SEND_REQUEST: u32 = 11;
const OP_BUS_RESET: u32 = 12;
const OP_CYCLE_TIMER: u32 = 13;
const OP_GET_SPEED: u32 = 14;
const OP_REPLY: u32 = 0x80;

fn le32(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}
fn le64(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

/// A message from the preloaded library to the twin server.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TwinRequest<'a> {
    /// Open /dev/fw`device` (first message of an event connection).
    Open {
        /// The N of /dev/fwN.
        device: u32,
    },
    /// Bind this control connection to an event connection.
    Attach {
        /// The ID the server gave the event connection.
        connection: u64,
    },
    /// Which /dev/fwN exist.
    List,
    /// GET_INFO: the client's ABI version, the room for the ROM, the
    /// closure of later bus-reset events.
    GetInfo {
        /// Client ABI version.
        version: u32,
        /// Bytes of ROM the caller has room for.
        rom_length: u32,
        /// Closure of BUS_RESET events from now on.
        bus_reset_closure: u64,
    },
    /// SEND_REQUEST or SEND_BROADCAST_REQUEST with its payload.
    SendRequest {
        /// SEND_BROADCAST_REQUEST.
        broadcast: bool,
        /// The argument.
        args: SendRequestArgs,
        /// `args.length` bytes copied from `args.data`.
        payload: &'a [u8],
    },
    /// INITIATE_BUS_RESET (`short`: type 1).
    InitiateBusReset {
        /// A short (arbitrated) reset.
        short: bool,
    },
    /// GET_CYCLE_TIMER / GET_CYCLE_TIMER2.
    CycleTimer,
    /// GET_SPEED.
    GetSpeed,
}

/// Bytes a twin request can take at most (header and a 4096-byte payload).
pub const TWIN_MAX_MESSAGE: usize = 4096 + 64;

/// Where a SEND_REQUEST message's payload starts (after its header).
pub const SEND_REQUEST_PAYLOAD_AT: usize = 36;

/// Write the header of a SEND_REQUEST message in front of the
/// `args.length` payload bytes the caller already put at
/// [`SEND_REQUEST_PAYLOAD_AT`] in `out` (so that a payload is copied once,
/// straight from the program's buffer into the message). Returns the
/// message's length.
///
/// # Errors
/// [`Error::BufferTooSmall`] when `out` cannot hold header and payload.
pub fn emit_send_request_head(
    broadcast: bool,
    args: &SendRequestArgs,
    out: &mut [u8],
) -> Result<usize> {
    let total = SEND_REQUEST_PAYLOAD_AT + args.payload_len();
    if out.len() < total {
        return Err(Error::BufferTooSmall {
            what: "twin send request",
            needed: total,
            available: out.len(),
        });
    }
    put(out, 0, &OP_SEND_REQUEST.to_le_bytes())?;
    put(out, 4, &u32::from(broadcast).to_le_bytes())?;
    put(out, 8, &args.tcode.to_le_bytes())?;
    put(out, 12, &args.length.to_le_bytes())?;
    put(out, 16, &args.offset.to_le_bytes())?;
    put(out, 24, &args.closure.to_le_bytes())?;
    put(out, 32, &args.generation.to_le_bytes())?;
    Ok(total)
}

impl<'a> TwinRequest<'a> {
    /// Whether the server answers this message with a [`TwinReply`]:
    /// every message but SEND_REQUEST's, whose outcome is its completion
    /// event (see the module docs).
    pub fn expects_reply(&self) -> bool {
        !matches!(self, TwinRequest::SendRequest { .. })
    }

    /// Parse one message.
    ///
    /// # Errors
    /// [`Error::Truncated`], [`Error::LengthExceedsBuffer`] (payload
    /// length), [`Error::InvalidValue`] for an unknown operation.
    pub fn parse(b: &'a [u8]) -> Result<TwinRequest<'a>> {
        let t = || truncated("twin request", 8, b.len());
        let op = le32(b, 0).ok_or_else(t)?;
        Ok(match op {
            OP_OPEN => TwinRequest::Open {
                device: le32(b, 4).ok_or_else(t)?,
            },
            OP_ATTACH => TwinRequest::Attach {
                connection: le64(b, 4).ok_or_else(t)?,
            },
            OP_LIST => TwinRequest::List,
            OP_GET_INFO => TwinRequest::GetInfo {
                version: le32(b, 4).ok_or_else(t)?,
                rom_length: le32(b, 8).ok_or_else(t)?,
                bus_reset_closure: le64(b, 12).ok_or_else(t)?,
            },
            OP_SEND_REQUEST => {
                let args = SendRequestArgs {
                    tcode: le32(b, 8).ok_or_else(t)?,
                    length: le32(b, 12).ok_or_else(t)?,
                    offset: le64(b, 16).ok_or_else(t)?,
                    closure: le64(b, 24).ok_or_else(t)?,
                    data: 0,
                    generation: le32(b, 32).ok_or_else(t)?,
                };
                let payload = b.get(SEND_REQUEST_PAYLOAD_AT..).unwrap_or(&[]);
                if payload.len() != args.payload_len() {
                    return Err(Error::LengthExceedsBuffer {
                        what: "twin send request payload",
                        declared: args.payload_len(),
                        available: payload.len(),
                    });
                }
                TwinRequest::SendRequest {
                    broadcast: le32(b, 4).ok_or_else(t)? != 0,
                    args,
                    payload,
                }
            }
            OP_BUS_RESET => TwinRequest::InitiateBusReset {
                short: le32(b, 4).ok_or_else(t)? != 0,
            },
            OP_CYCLE_TIMER => TwinRequest::CycleTimer,
            OP_GET_SPEED => TwinRequest::GetSpeed,
            other => {
                return Err(Error::InvalidValue {
                    what: "twin request operation",
                    value: other,
                });
            }
        })
    }

    /// Write the message; returns its length.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, out: &mut [u8]) -> Result<usize> {
        let le = |v: u32| v.to_le_bytes();
        match *self {
            TwinRequest::Open { device } => {
                put(out, 0, &le(OP_OPEN))?;
                put(out, 4, &le(device))?;
                Ok(8)
            }
            TwinRequest::Attach { connection } => {
                put(out, 0, &le(OP_ATTACH))?;
                put(out, 4, &connection.to_le_bytes())?;
                Ok(12)
            }
            TwinRequest::List => {
                put(out, 0, &le(OP_LIST))?;
                Ok(4)
            }
            TwinRequest::GetInfo {
                version,
                rom_length,
                bus_reset_closure,
            } => {
                put(out, 0, &le(OP_GET_INFO))?;
                put(out, 4, &le(version))?;
                put(out, 8, &le(rom_length))?;
                put(out, 12, &bus_reset_closure.to_le_bytes())?;
                Ok(20)
            }
            TwinRequest::SendRequest {
                broadcast,
                args,
                payload,
            } => {
                put(out, SEND_REQUEST_PAYLOAD_AT, payload)?;
                let args = SendRequestArgs {
                    length: payload.len() as u32,
                    ..args
                };
                emit_send_request_head(broadcast, &args, out)
            }
            TwinRequest::InitiateBusReset { short } => {
                put(out, 0, &le(OP_BUS_RESET))?;
                put(out, 4, &le(u32::from(short)))?;
                Ok(8)
            }
            TwinRequest::CycleTimer => {
                put(out, 0, &le(OP_CYCLE_TIMER))?;
                Ok(4)
            }
            TwinRequest::GetSpeed => {
                put(out, 0, &le(OP_GET_SPEED))?;
                Ok(4)
            }
        }
    }
}

/// The server's answer to one twin request: an errno (0: success), one
/// value (a connection ID, the kernel's ABI version, a speed code, a
/// cycle timer) and a payload.
///
/// Payloads: GET_INFO: the card index (u32), the ROM's full length in
/// bytes (u32), the bus-reset record ([`BUS_RESET_EVENT_LEN`] bytes, its
/// closure the one asked for), then the ROM (at most the room asked
/// for); GET_CYCLE_TIMER: the bus time in microseconds (u64); LIST: the
/// device numbers (u32 each).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TwinReply<'a> {
    /// 0, or the errno the ioctl fails with.
    pub errno: i32,
    /// The call's value.
    pub value: u64,
    /// The call's payload.
    pub payload: &'a [u8],
}

impl<'a> TwinReply<'a> {
    /// Parse one reply.
    ///
    /// # Errors
    /// [`Error::Truncated`], [`Error::InvalidValue`] when it is not a reply.
    pub fn parse(b: &'a [u8]) -> Result<TwinReply<'a>> {
        let t = || truncated("twin reply", 16, b.len());
        let op = le32(b, 0).ok_or_else(t)?;
        if op != OP_REPLY {
            return Err(Error::InvalidValue {
                what: "twin reply tag",
                value: op,
            });
        }
        Ok(TwinReply {
            errno: le32(b, 4).ok_or_else(t)? as i32,
            value: le64(b, 8).ok_or_else(t)?,
            payload: b.get(16..).unwrap_or(&[]),
        })
    }

    /// Write the reply; returns its length.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, out: &mut [u8]) -> Result<usize> {
        put(out, 0, &OP_REPLY.to_le_bytes())?;
        put(out, 4, &(self.errno as u32).to_le_bytes())?;
        put(out, 8, &self.value.to_le_bytes())?;
        put(out, 16, self.payload)?;
        Ok(16 + self.payload.len())
    }
}

/// The head of a GET_INFO reply payload: (card, full ROM length, the
/// bus-reset record bytes, the ROM bytes sent).
///
/// # Errors
/// [`Error::Truncated`].
pub fn split_info_payload(p: &[u8]) -> Result<(u32, u32, &[u8], &[u8])> {
    let need = 8 + BUS_RESET_EVENT_LEN;
    let t = || truncated("twin GET_INFO payload", need, p.len());
    let card = le32(p, 0).ok_or_else(t)?;
    let rom_length = le32(p, 4).ok_or_else(t)?;
    let record = p.get(8..need).ok_or_else(t)?;
    Ok((card, rom_length, record, p.get(need..).unwrap_or(&[])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ioctl_numbers_match_the_kernel_header() {
        // _IOWR('#', 0, 40), _IOW('#', 1, 40), _IOW('#', 0x12, 40),
        // _IO('#', 0x11): the values strace prints on x86-64.
        assert_eq!(IOC_GET_INFO, 0xc028_2300);
        assert_eq!(IOC_SEND_REQUEST, 0x4028_2301);
        assert_eq!(IOC_SEND_BROADCAST_REQUEST, 0x4028_2312);
        assert_eq!(IOC_INITIATE_BUS_RESET, 0x4004_2305);
        assert_eq!(IOC_GET_SPEED, 0x2311);
        assert_eq!(IOC_GET_CYCLE_TIMER2, 0xc018_2314);
        assert_eq!(Ioctl::from_request(0xc028_2300), Some(Ioctl::GetInfo));
        // The right number with the wrong size is not the ioctl.
        assert_eq!(Ioctl::from_request(0xc024_2300), None);
        assert_eq!(Ioctl::from_request(0x5401), None);
    }

    #[test]
    fn send_request_checks_follow_the_kernel() {
        let req = |tcode, length, offset| SendRequestArgs {
            tcode,
            length,
            offset,
            closure: 0,
            data: 0,
            generation: 0,
        };
        assert_eq!(req(4, 4, 0).check(false, 2), Ok(()));
        assert_eq!(req(0, 2, 0).check(false, 2), Err(errno::EINVAL));
        assert_eq!(req(2, 4, 0).check(false, 2), Err(errno::EINVAL));
        assert_eq!(req(5, 2048, 0).check(false, 2), Ok(()));
        assert_eq!(req(5, 2052, 0).check(false, 2), Err(errno::EIO));
        assert_eq!(req(1, 8192, 0).check(false, 5), Err(errno::EIO));
        assert_eq!(
            req(0, 4, 0xFFFF_F000_07FC).check(true, 2),
            Err(errno::EACCES)
        );
        assert_eq!(req(0, 4, BROADCAST_MIN_OFFSET).check(true, 2), Ok(()));
        assert_eq!(
            req(4, 4, BROADCAST_MIN_OFFSET).check(true, 2),
            Err(errno::EINVAL)
        );
        // Broadcasts go at S100: 512 bytes at most.
        assert_eq!(
            req(1, 516, BROADCAST_MIN_OFFSET).check(true, 2),
            Err(errno::EIO)
        );
    }

    #[test]
    fn response_layouts_and_the_short_data_quirk() {
        let mut out = [0xA5u8; 64];
        let n = emit_response(4, 7, 0, &[1, 2, 3, 4], (0, 0), &mut out).unwrap();
        assert_eq!(n, 28);
        assert_eq!(&out[20..24], &[1, 2, 3, 4]);
        assert_eq!(&out[24..28], &[1, 2, 3, 4]);
        assert_eq!(u32_at(&out, 8), Some(EVENT_RESPONSE));
        let e = ResponseEvent::parse(&out[..n]).unwrap();
        assert_eq!((e.closure, e.rcode, e.data), (7, 0, &[1, 2, 3, 4][..]));

        let mut out = [0xA5u8; 64];
        let n = emit_response(5, 9, 0, &[9; 8], (0, 0), &mut out).unwrap();
        assert_eq!(n, 32);
        assert_eq!(&out[20..28], &[9; 8]);

        let mut out = [0xA5u8; 64];
        let n = emit_response(6, 9, rcode::NO_ACK, &[], (3, 4), &mut out).unwrap();
        assert_eq!(n, 32);
        assert_eq!(u32_at(&out, 8), Some(EVENT_RESPONSE2));
        assert_eq!(u32_at(&out, 12), Some(rcode::NO_ACK));
        assert_eq!(u32_at(&out, 20), Some(3));
        let e = ResponseEvent::parse(&out[..n]).unwrap();
        assert_eq!(e.rcode, rcode::NO_ACK);
        assert!(e.data.is_empty());
        // A length that claims more than the event holds is refused.
        let mut bad = out;
        bad[16] = 200;
        assert!(ResponseEvent::parse(&bad[..n]).is_err());
    }

    #[test]
    fn bus_reset_record_round_trips() {
        let r = BusResetRecord {
            node_id: 0xffc1,
            local_node_id: 0xffc8,
            bm_node_id: 0xffc8,
            irm_node_id: 0xffc8,
            root_node_id: 0xffc8,
            generation: 3,
        };
        let mut out = [0xA5u8; 40];
        assert_eq!(r.emit(42, &mut out).unwrap(), 40);
        assert_eq!(BusResetRecord::parse(&out).unwrap(), (42, r));
        assert!(BusResetRecord::parse(&out[..30]).is_err());
    }

    #[test]
    fn twin_messages_round_trip_and_reject_bad_lengths() {
        let payload = [1u8, 2, 3, 4, 5, 6, 7, 8];
        let args = SendRequestArgs {
            tcode: 1,
            length: 8,
            offset: 0xFFFF_FFFF_0000,
            closure: 99,
            data: 0,
            generation: 5,
        };
        let msgs = [
            TwinRequest::Open { device: 3 },
            TwinRequest::Attach { connection: 77 },
            TwinRequest::List,
            TwinRequest::GetInfo {
                version: 4,
                rom_length: 1024,
                bus_reset_closure: 5,
            },
            TwinRequest::SendRequest {
                broadcast: false,
                args,
                payload: &payload,
            },
            TwinRequest::InitiateBusReset { short: true },
            TwinRequest::CycleTimer,
            TwinRequest::GetSpeed,
        ];
        for m in msgs {
            let mut out = [0xA5u8; 128];
            let n = m.emit(&mut out).unwrap();
            assert_eq!(TwinRequest::parse(&out[..n]).unwrap(), m);
        }
        let mut out = [0u8; 128];
        let n = msgs[4].emit(&mut out).unwrap();
        assert!(TwinRequest::parse(&out[..n - 1]).is_err());
        assert!(TwinRequest::parse(&[9, 0, 0, 0]).is_err());
        assert!(TwinRequest::parse(&[]).is_err());
        let reply = TwinReply {
            errno: errno::EACCES,
            value: 6,
            payload: &payload,
        };
        let n = reply.emit(&mut out).unwrap();
        assert_eq!(TwinReply::parse(&out[..n]).unwrap(), reply);
        assert!(TwinReply::parse(&out[..10]).is_err());
    }

    #[test]
    fn a_send_request_head_fronts_a_payload_already_in_place() {
        let args = SendRequestArgs {
            tcode: 1,
            length: 8,
            offset: 0xFFFF_FFFF_0000,
            closure: 42,
            data: 0,
            generation: 3,
        };
        let payload = [9u8, 8, 7, 6, 5, 4, 3, 2];
        let mut out = [0xA5u8; 64];
        out[SEND_REQUEST_PAYLOAD_AT..SEND_REQUEST_PAYLOAD_AT + 8].copy_from_slice(&payload);
        let n = emit_send_request_head(true, &args, &mut out).unwrap();
        assert_eq!(n, 44);
        let parsed = TwinRequest::parse(&out[..n]).unwrap();
        assert_eq!(
            parsed,
            TwinRequest::SendRequest {
                broadcast: true,
                args,
                payload: &payload,
            }
        );
        // The same bytes as the message emitted whole.
        let mut whole = [0x5Au8; 64];
        assert_eq!(parsed.emit(&mut whole).unwrap(), n);
        assert_eq!(whole[..n], out[..n]);
        // No room for the payload the arguments declare.
        let mut short = [0u8; 43];
        assert!(emit_send_request_head(false, &args, &mut short).is_err());
        // Only SEND_REQUEST goes without a reply.
        assert!(!parsed.expects_reply());
        assert!(TwinRequest::GetSpeed.expects_reply());
        assert!(
            TwinRequest::GetInfo {
                version: 6,
                rom_length: 0,
                bus_reset_closure: 0
            }
            .expects_reply()
        );
    }

    proptest::proptest! {
        /// Any bytes from a client or the server, of any length: every
        /// parser answers Ok or a named error, never a panic; what parses
        /// as a twin request emits back within its own length.
        #[test]
        fn any_bytes_parse_or_fail_cleanly(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..200)) {
            let _ = GetInfoArgs::parse(&bytes);
            let _ = SendRequestArgs::parse(&bytes);
            let _ = BusResetRecord::parse(&bytes);
            let _ = ResponseEvent::parse(&bytes);
            let _ = TwinReply::parse(&bytes);
            if let Ok(request) = TwinRequest::parse(&bytes) {
                let mut out = [0u8; 4096];
                let n = request.emit(&mut out).unwrap();
                proptest::prop_assert!(n <= bytes.len());
            }
        }
    }
}
