//! Sequence-number bookkeeping on the receiving side.

/// What a received sequence number says about the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeqEvent {
    /// The first message, or the one expected.
    InOrder,
    /// `missing` messages were lost before this one.
    Gap {
        /// How many sequence numbers were skipped.
        missing: u32,
    },
    /// A message already seen (same or earlier number): a duplicate or a reordering.
    Repeat,
}

/// Follows one direction's sequence numbers.
#[derive(Debug, Clone, Copy, Default)]
pub struct SeqTracker {
    next: Option<u32>,
}

/// Further back than this is a repeat, not a gap of nearly 2³² messages.
const REPEAT_WINDOW: u32 = 1 << 31;

impl SeqTracker {
    /// A tracker that takes the first number it sees as the start.
    pub const fn new() -> Self {
        Self { next: None }
    }

    /// Accounts for a received `seq`.
    pub fn observe(&mut self, seq: u32) -> SeqEvent {
        let event = match self.next {
            None => SeqEvent::InOrder,
            Some(next) if seq == next => SeqEvent::InOrder,
            Some(next) => {
                let ahead = seq.wrapping_sub(next);
                if ahead < REPEAT_WINDOW {
                    SeqEvent::Gap { missing: ahead }
                } else {
                    // Behind: keep expecting `next`.
                    return SeqEvent::Repeat;
                }
            }
        };
        self.next = Some(seq.wrapping_add(1));
        event
    }
}
