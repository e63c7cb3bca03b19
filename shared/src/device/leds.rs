//! LED duty (per mille, as commanded) to PWM compare values.

use crate::protocol::LedDuty;

/// Compare values for a PWM timer whose full duty is `max`: `duty · max / 1000`, rounded,
/// red, green, blue. Duties above 1000 (refused by the controller) saturate at `max`.
pub fn compare_values(duty: LedDuty, max: u16) -> [u16; 3] {
    [duty.red, duty.green, duty.blue].map(|d| {
        let d = u32::from(d.min(LedDuty::FULL));
        ((d * u32::from(max) + 500) / 1000) as u16
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duty_maps_to_compare_values_monotonically_and_at_both_ends() {
        let at = |d: u16, max| {
            compare_values(
                LedDuty {
                    red: d,
                    green: d,
                    blue: d,
                },
                max,
            )[0]
        };
        for max in [1u16, 99, 999, 1000, 4095, u16::MAX] {
            assert_eq!(at(0, max), 0);
            assert_eq!(at(1000, max), max);
            assert_eq!(at(5000, max), max, "saturates");
            let mut last = 0;
            for d in 0..=1000 {
                let v = at(d, max);
                assert!(v >= last);
                last = v;
            }
        }
        assert_eq!(at(500, 999), 500); // 499.5 rounds up
        assert_eq!(compare_values(LedDuty::ALL_ON, 240), [240; 3]);
        let mixed = LedDuty {
            red: 250,
            green: 0,
            blue: 1000,
        };
        assert_eq!(compare_values(mixed, 400), [100, 0, 400]);
    }
}
