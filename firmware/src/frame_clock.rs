//! Where the belt was when a captured frame began.
//!
//! A frame trigger only arms the camera interface; the snapshot starts with the next frame
//! the sensor sends, up to a frame period later (33 ms: 8 camera pixels of belt at
//! 26 mm/s). The frame's position is therefore taken from the step count at its start, as
//! the camera's frame-sync interrupt saw it, not from the trigger.
//!
//! The interface raises a frame-sync edge ([`frame_edge`]) when the sensor enters
//! vertical blanking — the end of each frame — and only while a capture is armed. So a
//! capture armed in the middle of a frame sees two edges (the end of the frame it skipped,
//! then the end of its own) and its frame began at the first; one armed during blanking
//! sees only its own end edge, and its frame began just after the arming. With no edges
//! at all (an interface without the interrupt), the arming is the best there is.

use crate::roller;
use core::cell::Cell;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;

/// The step counts at the last two frame-sync edges, and how many there have been.
#[derive(Clone, Copy)]
struct Edges {
    before_last: u64,
    last: u64,
    count: u32,
}

static EDGES: Mutex<CriticalSectionRawMutex, Cell<Edges>> = Mutex::new(Cell::new(Edges {
    before_last: 0,
    last: 0,
    count: 0,
}));

/// The camera interface's frame-sync interrupt: a frame ended (vertical blanking began).
pub fn frame_edge() {
    edge_at(roller::steps());
}

fn edge_at(steps: u64) {
    EDGES.lock(|e| {
        let Edges { last, count, .. } = e.get();
        e.set(Edges {
            before_last: last,
            last: steps,
            count: count.wrapping_add(1),
        });
    });
}

/// A capture about to start: the step count and the edges seen so far.
#[derive(Debug, Clone, Copy)]
pub struct Armed {
    steps: u64,
    edges: u32,
}

/// Call just before a capture starts.
pub fn arm() -> Armed {
    arm_at(roller::steps())
}

fn arm_at(steps: u64) -> Armed {
    Armed {
        steps,
        edges: EDGES.lock(|e| e.get().count),
    }
}

impl Armed {
    /// The step count at which the captured frame began; call when its capture completed
    /// (before the next frame ends).
    pub fn frame_start(&self) -> u64 {
        let e = EDGES.lock(Cell::get);
        if e.count.wrapping_sub(self.edges) >= 2 {
            e.before_last
        } else {
            self.steps
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // One test: the edges are global.
    #[test]
    fn a_frame_begins_at_its_own_start_edge_or_at_the_arming() {
        // Armed mid-frame: the skipped frame's end edge starts the captured frame.
        let armed = arm_at(100);
        edge_at(112);
        edge_at(130);
        assert_eq!(armed.frame_start(), 112);
        // Armed in the blanking: only the captured frame's end edge.
        let armed = arm_at(140);
        edge_at(158);
        assert_eq!(armed.frame_start(), 140);
        // No interrupt wired: the arming.
        let armed = arm_at(200);
        assert_eq!(armed.frame_start(), 200);
        // A frame skipped too (three edges): still the edge before the last.
        let armed = arm_at(300);
        for s in [305, 323, 341] {
            edge_at(s);
        }
        assert_eq!(armed.frame_start(), 323);
    }
}
