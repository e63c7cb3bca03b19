//! Sequence-number bookkeeping on the receiving side.
//!
//! A sender numbers its messages up by one. The receiver takes the expected number, and
//! a small jump ahead (messages lost on the way). Anything else is off the sequence: a
//! number behind (a duplicate, or a recording out of order) or far ahead (a stray or
//! crafted message) is not taken, so that one such message cannot make every good one
//! after it look old. The sender's numbering is taken to have moved only when the
//! message after an off-sequence one continues from it: a device that restarted its
//! numbering (a reset) is followed from its second message on.

/// What a received sequence number says about the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeqEvent {
    /// The first message, or the one expected.
    InOrder,
    /// `missing` messages were lost before this one (at most [`MAX_GAP`]).
    Gap {
        /// How many sequence numbers were skipped.
        missing: u32,
    },
    /// A number already passed (same or earlier): a duplicate or a reordering. Not taken.
    Repeat,
    /// A number further ahead than [`MAX_GAP`]: more likely a stray than that many lost
    /// messages. Not taken.
    FarAhead,
    /// The message after an off-sequence one ([`SeqEvent::Repeat`] or
    /// [`SeqEvent::FarAhead`]) continues its numbering: the sender's numbering moved
    /// there (a restart), and is followed from here. Taken.
    Renumbered,
}

/// The largest jump ahead taken as messages lost on the way.
pub const MAX_GAP: u32 = 1024;

/// Follows one direction's sequence numbers.
#[derive(Debug, Clone, Copy, Default)]
pub struct SeqTracker {
    /// The number expected next.
    next: Option<u32>,
    /// The number after the last off-sequence message: where a new numbering would go on.
    after_off: Option<u32>,
}

impl SeqTracker {
    /// A tracker that takes the first number it sees as the start.
    pub const fn new() -> Self {
        Self {
            next: None,
            after_off: None,
        }
    }

    /// Accounts for a received `seq`.
    pub fn observe(&mut self, seq: u32) -> SeqEvent {
        let Some(next) = self.next else {
            return self.follow(seq, SeqEvent::InOrder);
        };
        if seq == next {
            return self.follow(seq, SeqEvent::InOrder);
        }
        if self.after_off == Some(seq) {
            return self.follow(seq, SeqEvent::Renumbered);
        }
        let ahead = seq.wrapping_sub(next);
        if ahead <= MAX_GAP {
            return self.follow(seq, SeqEvent::Gap { missing: ahead });
        }
        self.after_off = Some(seq.wrapping_add(1));
        // Behind: within half the number space back (beyond it, far ahead).
        if ahead >= 1 << 31 {
            SeqEvent::Repeat
        } else {
            SeqEvent::FarAhead
        }
    }

    /// Takes `seq` as the sequence's current number.
    fn follow(&mut self, seq: u32, event: SeqEvent) -> SeqEvent {
        self.next = Some(seq.wrapping_add(1));
        self.after_off = None;
        event
    }
}
