//! The three LEDs: PWM channels 1–3 of TIM4 (PD12 red, PD13 green, PD14 blue), duty from
//! commands through the core's mapping.

use embassy_stm32::Peri;
use embassy_stm32::gpio::OutputType;
use embassy_stm32::peripherals::{PD12, PD13, PD14, TIM4};
use embassy_stm32::time::khz;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use rollfuse_core::device::leds::compare_values;
use rollfuse_core::protocol::LedDuty;

/// The LED driver.
pub struct Leds {
    pwm: SimplePwm<'static, TIM4>,
}

impl Leds {
    /// The timer's channels 1–3 on their pins at 20 kHz, the LEDs off.
    pub fn new(
        tim: Peri<'static, TIM4>,
        red: Peri<'static, PD12>,
        green: Peri<'static, PD13>,
        blue: Peri<'static, PD14>,
    ) -> Self {
        let mut pwm = SimplePwm::new(
            tim,
            Some(PwmPin::new(red, OutputType::PushPull)),
            Some(PwmPin::new(green, OutputType::PushPull)),
            Some(PwmPin::new(blue, OutputType::PushPull)),
            None,
            khz(20),
            Default::default(),
        );
        pwm.ch1().enable();
        pwm.ch2().enable();
        pwm.ch3().enable();
        let mut leds = Self { pwm };
        rollfuse_fw::effects::Leds::set(&mut leds, LedDuty::default());
        leds
    }
}

impl rollfuse_fw::effects::Leds for Leds {
    fn set(&mut self, duty: LedDuty) {
        // The timer's full duty fits 16 bits at the 20 kHz the LEDs run at.
        let max = self.pwm.ch1().max_duty_cycle().min(u32::from(u16::MAX)) as u16;
        let [r, g, b] = compare_values(duty, max);
        self.pwm.ch1().set_duty_cycle(u32::from(r));
        self.pwm.ch2().set_duty_cycle(u32::from(g));
        self.pwm.ch3().set_duty_cycle(u32::from(b));
    }
}
