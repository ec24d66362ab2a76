//! The FPGA1394/QLA motor-controller board protocol: addresses, register
//! quadlets, the real-time blocks and the broadcast (hub) protocol.
//!
//! Facts: `fpga-board.md` sections 1 to 7. Raw bits only: conversions to
//! amps, volts or radians belong to the host layer.
//!
//! - [`address`]: address spaces, the main-space register map
//!   ([`BoardRegister`](address::BoardRegister),
//!   [`AxisRegister`](address::AxisRegister)), hub and broadcast offsets.
//! - [`registers`]: typed codecs for every register quadlet (STATUS read and
//!   write, DAC, ADC, encoder words, versions, watchdog, ...).
//! - [`realtime`]: firmware revisions, board layouts and the real-time read
//!   and write blocks (checked views and meaning types).
//! - [`broadcast`]: the query word, status broadcasts, the hub block and the
//!   concatenated command block.
//! - [`extras`]: the PROMs and serial numbers, the 1-wire interface, the
//!   I/O expander and the Ethernet status (`fpga-board-extras.md`).
//! - [`fpga_v3`]: the FPGA V3's Ethernet status and control words and the
//!   MDIO window to its RTL8211F PHYs (`rev9-fpga-v3.md`).
//! - [`dqla`]: the DQLA's STATUS and DIGIN words and its MAX7301 I/O
//!   expanders' register-14 read-out.
//!
//! ```
//! use firelink_wire::qla::realtime::{BoardLayout, FirmwareRev};
//! use firelink_wire::qla::broadcast::hub_block_quadlets;
//! let qla1 = BoardLayout::qla1(FirmwareRev::Rev8);
//! assert_eq!(qla1.read_block_quadlets(), 32);
//! assert_eq!(qla1.write_block_quadlets(), 6);
//! // Two QLA1 Rev 8 boards: 67 quadlets in the hub block (fpga-board.md §6.4).
//! assert_eq!(hub_block_quadlets([qla1; 2]), 67);
//! ```

pub mod address;
pub mod broadcast;
pub mod dqla;
pub mod extras;
pub mod fpga_v3;
pub mod realtime;
pub mod registers;

/// The largest number of motors or encoders one board carries (DQLA: 8).
pub const MAX_AXES: usize = 8;
/// Board IDs are 0..=15 (a 4-bit rotary switch), `fpga-board.md` §2.
pub const MAX_BOARD_ID: u8 = 15;
/// Number of distinct board IDs.
pub const MAX_BOARDS: usize = 16;

/// Conversion between a field's raw bits and the Rust type its accessors use.
pub(crate) trait Bits: Copy {
    /// From the extracted (right-aligned) field bits.
    fn from_bits(bits: u32) -> Self;
    /// To the raw bits (inserting truncates to the field width).
    fn to_bits(self) -> u32;
}

impl Bits for bool {
    #[inline]
    fn from_bits(bits: u32) -> Self {
        bits != 0
    }
    #[inline]
    fn to_bits(self) -> u32 {
        u32::from(self)
    }
}

impl Bits for u8 {
    #[inline]
    fn from_bits(bits: u32) -> Self {
        bits as u8
    }
    #[inline]
    fn to_bits(self) -> u32 {
        u32::from(self)
    }
}

impl Bits for u16 {
    #[inline]
    fn from_bits(bits: u32) -> Self {
        bits as u16
    }
    #[inline]
    fn to_bits(self) -> u32 {
        u32::from(self)
    }
}

impl Bits for u32 {
    #[inline]
    fn from_bits(bits: u32) -> Self {
        bits
    }
    #[inline]
    fn to_bits(self) -> u32 {
        self
    }
}

/// Define a register quadlet as a `u32` newtype whose bit fields each get a
/// getter, a setter and a builder, all from one [`Field`](crate::field::Field)
/// constant.
macro_rules! quadlet_register {
    (
        $(#[$attr:meta])*
        pub struct $name:ident {
            $(
                $(#[$fattr:meta])*
                $get:ident, $set:ident, $with:ident: $ty:ty = $field:path;
            )*
        }
    ) => {
        $(#[$attr])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
        pub struct $name(pub u32);

        impl $name {
            /// The raw quadlet.
            #[inline]
            pub const fn raw(self) -> u32 {
                self.0
            }

            $(
                $(#[$fattr])*
                #[inline]
                pub fn $get(self) -> $ty {
                    <$ty as $crate::qla::Bits>::from_bits($field.extract(self.0))
                }

                #[doc = concat!("Set [`", stringify!($get), "`](Self::", stringify!($get),
                    ") (truncated to the field width).")]
                #[inline]
                pub fn $set(&mut self, value: $ty) {
                    self.0 = $field.insert(self.0, $crate::qla::Bits::to_bits(value));
                }

                #[doc = concat!("This quadlet with [`", stringify!($get), "`](Self::",
                    stringify!($get), ") replaced (builder form of [`", stringify!($set),
                    "`](Self::", stringify!($set), ")).")]
                #[must_use]
                #[inline]
                pub fn $with(mut self, value: $ty) -> Self {
                    self.$set(value);
                    self
                }
            )*
        }

        impl From<u32> for $name {
            #[inline]
            fn from(raw: u32) -> Self {
                $name(raw)
            }
        }

        impl From<$name> for u32 {
            #[inline]
            fn from(value: $name) -> u32 {
                value.0
            }
        }
    };
}

pub(crate) use quadlet_register;

/// Define a checked view of a buffer whose exact size a
/// [`BoardLayout`](crate::qla::realtime::BoardLayout) sets: the struct
/// (buffer and layout) with `new_unchecked`, `new_checked`, `check_len`
/// (against the layout's `$quadlets()`, errors naming `$what`), `layout`,
/// `as_bytes` and `into_inner`. The view's own accessors go in a separate
/// `impl`.
macro_rules! layout_view {
    (
        $(#[$attr:meta])*
        pub struct $name:ident;
        what: $what:literal,
        quadlets: $quadlets:ident,
    ) => {
        $(#[$attr])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub struct $name<T: AsRef<[u8]>> {
            buffer: T,
            layout: $crate::qla::realtime::BoardLayout,
        }

        impl<T: AsRef<[u8]>> $name<T> {
            /// Wrap a buffer without checking it.
            pub const fn new_unchecked(
                buffer: T,
                layout: $crate::qla::realtime::BoardLayout,
            ) -> $name<T> {
                $name { buffer, layout }
            }

            /// Wrap a buffer after checking its length.
            ///
            /// # Errors
            /// See [`check_len`](Self::check_len).
            pub fn new_checked(
                buffer: T,
                layout: $crate::qla::realtime::BoardLayout,
            ) -> $crate::Result<$name<T>> {
                let view = Self::new_unchecked(buffer, layout);
                view.check_len()?;
                Ok(view)
            }

            #[doc = concat!("Check that the buffer is exactly the layout's ", $what, ".")]
            ///
            /// # Errors
            /// [`Error::NotQuadletAligned`](crate::Error::NotQuadletAligned) or
            /// [`Error::BlockSize`](crate::Error::BlockSize).
            #[inline]
            pub fn check_len(&self) -> $crate::Result<()> {
                $crate::qla::check_exact(
                    $what,
                    self.buffer.as_ref().len(),
                    self.layout.$quadlets(),
                )
            }

            /// The layout.
            pub fn layout(&self) -> $crate::qla::realtime::BoardLayout {
                self.layout
            }

            /// The underlying bytes.
            pub fn as_bytes(&self) -> &[u8] {
                self.buffer.as_ref()
            }

            /// Consume the view, returning the buffer.
            pub fn into_inner(self) -> T {
                self.buffer
            }
        }
    };
}

pub(crate) use layout_view;

/// Check that the buffer is exactly `quadlets` quadlets long.
#[inline]
pub(crate) fn check_exact(what: &'static str, len: usize, quadlets: usize) -> crate::Result<()> {
    if len % 4 != 0 {
        return Err(crate::Error::NotQuadletAligned { what, len });
    }
    if len / 4 != quadlets {
        return Err(crate::Error::BlockSize {
            what,
            expected: quadlets,
            found: len / 4,
        });
    }
    Ok(())
}

pub(crate) use crate::error::check_max;
