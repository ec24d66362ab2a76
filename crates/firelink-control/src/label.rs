//! Small `Copy` names and board sets that fault reports can carry without
//! allocating.

use core::fmt;

/// A short, inline, `Copy` name such as `"MTML[3]"` or `"PSM2"`.
///
/// Names longer than [`Label::CAPACITY`] bytes are cut at the last character
/// boundary that fits, so a `Label` is always valid UTF-8. Built once at
/// setup from the configuration; carried by [`FaultReport`](crate::FaultReport)
/// so that a fault names the joint or board without touching the heap.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Label {
    bytes: [u8; Label::CAPACITY],
    len: u8,
}

impl Label {
    /// Longest name kept, in bytes.
    pub const CAPACITY: usize = 31;

    /// The empty label.
    pub const EMPTY: Label = Label {
        bytes: [0; Label::CAPACITY],
        len: 0,
    };

    /// A label holding `name`, cut to [`Label::CAPACITY`] bytes on a
    /// character boundary.
    pub fn new(name: &str) -> Label {
        let mut end = name.len().min(Self::CAPACITY);
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        let mut bytes = [0u8; Self::CAPACITY];
        let src = name.as_bytes().get(..end).unwrap_or_default();
        for (dst, src) in bytes.iter_mut().zip(src) {
            *dst = *src;
        }
        Label {
            bytes,
            // `end` <= 31, so it fits.
            len: end as u8,
        }
    }

    /// A joint label in the configuration's own indexing: `robot[index]`
    /// (for example `MTML[3]` is the fourth actuator of MTML, `actuator_id` 3).
    pub fn joint(robot: &str, index: usize) -> Label {
        use fmt::Write;
        let mut w = LabelWriter(Label::EMPTY);
        // Writing into a Label never fails; overlong text is cut.
        let _ = write!(w, "{robot}[{index}]");
        w.0
    }

    /// The name as a string slice.
    pub fn as_str(&self) -> &str {
        let bytes = self.bytes.get(..usize::from(self.len)).unwrap_or_default();
        // Only whole characters are ever stored.
        core::str::from_utf8(bytes).unwrap_or_default()
    }

    /// Whether the label is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl Default for Label {
    fn default() -> Self {
        Label::EMPTY
    }
}

impl fmt::Debug for Label {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

impl fmt::Display for Label {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl From<&str> for Label {
    fn from(s: &str) -> Self {
        Label::new(s)
    }
}

/// Appends to a label, cutting on a character boundary when full.
struct LabelWriter(Label);

impl fmt::Write for LabelWriter {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for c in s.chars() {
            let mut buf = [0u8; 4];
            let enc = c.encode_utf8(&mut buf).as_bytes();
            let start = usize::from(self.0.len);
            let end = start + enc.len();
            let Some(dst) = self.0.bytes.get_mut(start..end) else {
                return Ok(());
            };
            dst.copy_from_slice(enc);
            self.0.len = end as u8;
        }
        Ok(())
    }
}

/// A set of board IDs (0..=15, the 4-bit rotary switch), as a 16-bit mask.
///
/// Bit *i* set means board *i* is in the set: the same layout as the board
/// mask of the broadcast query (`fpga-board.md` §6).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct BoardSet(pub u16);

impl BoardSet {
    /// No boards.
    pub const EMPTY: BoardSet = BoardSet(0);

    /// Whether `board_id` is in the set (IDs above 15 never are).
    pub fn contains(self, board_id: u8) -> bool {
        board_id < 16 && self.0 & (1 << board_id) != 0
    }

    /// The set with `board_id` added (IDs above 15 are ignored).
    #[must_use]
    pub fn with(self, board_id: u8) -> BoardSet {
        if board_id < 16 {
            BoardSet(self.0 | (1 << board_id))
        } else {
            self
        }
    }

    /// Adds `board_id` (IDs above 15 are ignored).
    pub fn insert(&mut self, board_id: u8) {
        *self = self.with(board_id);
    }

    /// Boards in `self` that are not in `other`.
    #[must_use]
    pub fn minus(self, other: BoardSet) -> BoardSet {
        BoardSet(self.0 & !other.0)
    }

    /// The lowest board ID in the set.
    pub fn first(self) -> Option<u8> {
        if self.0 == 0 {
            None
        } else {
            Some(self.0.trailing_zeros() as u8)
        }
    }

    /// Number of boards in the set.
    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// Whether the set is empty.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The board IDs in ascending order. (One step per board in the set,
    /// the lowest bit taken off each time: the cycle walks the expected
    /// boards twice, and a filter over all 16 IDs cost more.)
    pub fn iter(self) -> impl Iterator<Item = u8> {
        let mut rest = self.0;
        core::iter::from_fn(move || {
            if rest == 0 {
                return None;
            }
            let id = rest.trailing_zeros() as u8;
            rest &= rest - 1;
            Some(id)
        })
    }
}

impl fmt::Debug for BoardSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_set().entries(self.iter()).finish()
    }
}

impl FromIterator<u8> for BoardSet {
    fn from_iter<I: IntoIterator<Item = u8>>(iter: I) -> Self {
        let mut set = BoardSet::EMPTY;
        for b in iter {
            set.insert(b);
        }
        set
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_cuts_on_char_boundary() {
        let l = Label::new("abcdefghijklmnopqrstuvwxyz01234é");
        assert_eq!(l.as_str(), "abcdefghijklmnopqrstuvwxyz01234");
        let l = Label::new("ééééééééééééééééé"); // 34 bytes
        assert_eq!(l.as_str().len(), 30);
        assert_eq!(Label::joint("MTML", 3).as_str(), "MTML[3]");
        let long = Label::joint("a_very_long_robot_name_indeed_yes", 12);
        assert_eq!(long.as_str().len(), Label::CAPACITY);
    }

    #[test]
    fn board_set() {
        let s: BoardSet = [0u8, 3, 7, 20].into_iter().collect();
        assert_eq!(s.0, 0b1000_1001);
        assert!(s.contains(3) && !s.contains(4) && !s.contains(20));
        assert_eq!(s.len(), 3);
        assert_eq!(s.minus(BoardSet(1)).first(), Some(3));
        assert_eq!(s.iter().collect::<Vec<_>>(), vec![0, 3, 7]);
        assert_eq!(BoardSet::EMPTY.first(), None);
        // Every set lists its IDs in ascending order.
        for mask in 0..=u16::MAX {
            let set = BoardSet(mask);
            let ids: Vec<u8> = (0u8..16).filter(|&b| set.contains(b)).collect();
            assert_eq!(set.iter().collect::<Vec<_>>(), ids, "{mask:#06x}");
        }
    }
}
