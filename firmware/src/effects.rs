//! Accepted commands' effects reach the hardware here: LED duties, roller orders and the
//! pipeline's orders.

use crate::liveness::{self, Task};
use crate::roller::{self, Order};
use crate::signals::{Accepted, EFFECTS, STREAM, StreamOrder};
use embassy_futures::select::{Either, select};
use embassy_time::Timer;
use rollfuse_core::device::{Effect, session as stream};
use rollfuse_core::protocol::LedDuty;

/// The three LEDs.
pub trait Leds {
    /// Sets the duties (per mille).
    fn set(&mut self, duty: LedDuty);
}

/// Carries out effects forever. A full queue ahead (the pipeline busy sending, the roller
/// between steps) is waited out, beating: those tasks beat for themselves.
pub async fn run(leds: &mut impl Leds) {
    loop {
        liveness::beat(Task::Effects);
        let next = select(EFFECTS.receive(), Timer::after(liveness::BEAT)).await;
        let Either::First(Accepted {
            effect,
            stops,
            stream_stops,
        }) = next
        else {
            continue;
        };
        let order = |order| liveness::waiting(Task::Effects, roller::ORDERS.send(order));
        match effect {
            Effect::Leds(duty) => leds.set(duty),
            Effect::Roller(command) => order(Order::Roller { command, stops }).await,
            Effect::Configure(cfg) => {
                let px = u16::try_from(cfg.spacing_px()).unwrap_or(u16::MAX);
                order(Order::FrameSpacing(px)).await;
            }
            Effect::StreamStart | Effect::StreamStop | Effect::CaptureRaw(_) | Effect::None => {}
        }
        if let Some(order) = stream::Order::of(effect) {
            let order = StreamOrder {
                order,
                stops: stream_stops,
            };
            liveness::waiting(Task::Effects, STREAM.send(order)).await;
        }
    }
}
