//! Accepted commands' effects reach the hardware here: LED duties, roller orders and the
//! pipeline's orders.

use crate::liveness;
use crate::roller::{self, Order};
use crate::signals::{EFFECTS, STREAM};
use embassy_futures::select::{Either, select};
use embassy_time::Timer;
use rollfuse_core::device::{Effect, session as stream};
use rollfuse_core::protocol::LedDuty;

/// The three LEDs.
pub trait Leds {
    /// Sets the duties (per mille).
    fn set(&mut self, duty: LedDuty);
}

/// Carries out effects forever.
pub async fn run(leds: &mut impl Leds) {
    loop {
        liveness::beat(liveness::Task::Effects);
        let next = select(EFFECTS.receive(), Timer::after(liveness::BEAT)).await;
        let Either::First(effect) = next else {
            continue;
        };
        match effect {
            Effect::Leds(duty) => leds.set(duty),
            Effect::Roller(cmd) => roller::ORDERS.send(Order::Roller(cmd)).await,
            Effect::Configure(cfg) => {
                let px = u16::try_from(cfg.spacing_px).unwrap_or(u16::MAX);
                roller::ORDERS.send(Order::FrameSpacing(px)).await;
            }
            Effect::StreamStart | Effect::StreamStop | Effect::CaptureRaw(_) | Effect::None => {}
        }
        if let Some(order) = stream::Order::of(effect) {
            STREAM.send(order).await;
        }
    }
}
