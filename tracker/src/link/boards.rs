//! Who is talking: per array id, the board behind it (its chip unique ID) and its runs, from
//! the `Hello` frames. Notices a reboot (a new boot count, or the sample index going back) and
//! a second board claiming an id another board already uses (two unique IDs under one id).

use std::collections::HashMap;

use aim_wire::{Frame, Hello, ResetCause, UNIQUE_ID_LEN};

/// What a `Hello` revealed about its board.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BoardEvent {
    /// The board started again since its last `Hello`.
    Reboot {
        /// Array id.
        array_id: u8,
        /// Why it started (as it reports it).
        cause: Option<ResetCause>,
        /// Its boot count now (0: not reported).
        boot_count: u32,
        /// The panic or fault message it recorded before the reset (empty if none).
        message: String,
    },
    /// A `Hello` under this id came from another chip than the last one did.
    DuplicateId {
        /// Array id.
        array_id: u8,
        /// The unique ID seen before, hex.
        before: String,
        /// The unique ID of this `Hello`, hex.
        now: String,
    },
}

/// The last `Hello` of one array id.
#[derive(Debug, Clone, Copy)]
struct Seen {
    unique_id: [u8; UNIQUE_ID_LEN],
    boot_count: u32,
    sample_index: u64,
}

/// Follows the `Hello` frames of every array id on a link.
#[derive(Debug, Default)]
pub struct Boards {
    seen: HashMap<u8, Seen>,
    /// Reboots noticed.
    pub reboots: u64,
    /// `Hello` frames whose unique ID differed from the previous one under the same id.
    pub duplicate_ids: u64,
}

/// A unique ID as lower-case hex (all zero: not reported).
pub fn unique_id_hex(id: &[u8; UNIQUE_ID_LEN]) -> String {
    id.iter().map(|b| format!("{b:02x}")).collect()
}

impl Boards {
    /// Nothing seen yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes a frame; returns what a `Hello` revealed (nothing for other kinds, or for the
    /// first `Hello` of an id, which is the board's start as far as this host knows).
    pub fn observe(&mut self, frame: &Frame) -> Vec<BoardEvent> {
        let aim_wire::Body::Hello(hello) = &frame.body else { return Vec::new() };
        let array_id = frame.header.array_id;
        let now = Seen {
            unique_id: hello.unique_id,
            boot_count: hello.boot_count,
            sample_index: frame.header.sample_index,
        };
        let mut events = Vec::new();
        if let Some(before) = self.seen.insert(array_id, now) {
            let reported = |id: &[u8; UNIQUE_ID_LEN]| id.iter().any(|&b| b != 0);
            if reported(&before.unique_id)
                && reported(&now.unique_id)
                && before.unique_id != now.unique_id
            {
                self.duplicate_ids += 1;
                events.push(BoardEvent::DuplicateId {
                    array_id,
                    before: unique_id_hex(&before.unique_id),
                    now: unique_id_hex(&now.unique_id),
                });
            } else if now.boot_count != before.boot_count || now.sample_index < before.sample_index
            {
                self.reboots += 1;
                events.push(reboot(array_id, hello));
            }
        }
        events
    }
}

fn reboot(array_id: u8, hello: &Hello) -> BoardEvent {
    BoardEvent::Reboot {
        array_id,
        cause: hello.reset_cause(),
        boot_count: hello.boot_count,
        message: hello.panic_message.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aim_wire::{Body, Header};

    fn hello(
        array_id: u8,
        sample_index: u64,
        uid: u8,
        boot_count: u32,
        cause: ResetCause,
    ) -> Frame {
        let mut h = Hello::new([0, 1, 0], 48_000, 1024, &[[0.0, 0.0]]);
        h.unique_id = [uid; UNIQUE_ID_LEN];
        h.boot_count = boot_count;
        h.reset_cause = cause.code();
        if cause == ResetCause::Panic {
            h.set_panic_message("src/processing.rs:9 boom");
        }
        Frame { header: Header { array_id, seq: 0, sample_index }, body: Body::Hello(h) }
    }

    #[test]
    fn a_new_boot_count_or_a_clock_going_back_is_a_reboot() {
        let mut boards = Boards::new();
        assert!(boards.observe(&hello(3, 0, 7, 1, ResetCause::PowerOn)).is_empty());
        assert!(boards.observe(&hello(3, 240_000, 7, 1, ResetCause::PowerOn)).is_empty());
        let events = boards.observe(&hello(3, 0, 7, 2, ResetCause::Panic));
        assert_eq!(
            events,
            [BoardEvent::Reboot {
                array_id: 3,
                cause: Some(ResetCause::Panic),
                boot_count: 2,
                message: "src/processing.rs:9 boom".into(),
            }]
        );
        // A power cycle restarts the boot count at 1, possibly the count seen last: the
        // sample index going back still tells.
        boards.observe(&hello(4, 480_000, 8, 1, ResetCause::PowerOn));
        let events = boards.observe(&hello(4, 0, 8, 1, ResetCause::PowerOn));
        assert!(matches!(events[..], [BoardEvent::Reboot { array_id: 4, boot_count: 1, .. }]));
        assert_eq!((boards.reboots, boards.duplicate_ids), (2, 0));
    }

    #[test]
    fn two_chips_under_one_id_are_reported() {
        let mut boards = Boards::new();
        boards.observe(&hello(5, 0, 0x11, 1, ResetCause::PowerOn));
        let events = boards.observe(&hello(5, 96_000, 0x22, 1, ResetCause::PowerOn));
        assert_eq!(
            events,
            [BoardEvent::DuplicateId {
                array_id: 5,
                before: "11".repeat(12),
                now: "22".repeat(12),
            }]
        );
        // Older firmware reports no unique ID: nothing to compare.
        boards.observe(&hello(6, 0, 0, 0, ResetCause::Unknown));
        assert!(boards.observe(&hello(6, 240_000, 0, 0, ResetCause::Unknown)).is_empty());
        assert_eq!((boards.reboots, boards.duplicate_ids), (0, 1));
    }
}
