//! The OV7725 camera's register set-up, and the frame timing it programs, as data: the
//! board's driver (`mcu::camera`) writes [`SETUP`] after a register reset; the host tests
//! derive the byte order, the window and the frame rate from those same writes.
//!
//! Timing, from the datasheet (CLKRC, COM4, and the frame of 576 × 278 pixel times at
//! QVGA, two pixel clocks a pixel in YUV):
//!
//! ```text
//! PCLK  = XCLK × PLL / (2 × (CLKRC[5:0] + 1))
//! frame = 2 × (576 + dummy pixels) × (278 + dummy lines) PCLK
//! ```
//!
//! XCLK is HSI / 3 = 21.33 MHz (MCO1). The PLL stays at its reset ×4 (COM4 0x41, written
//! anyway so the rate does not rest on a reset value); CLKRC 3 gives PCLK 10.67 MHz, 33.3
//! frames/s bare, and 31 dummy lines (ADVFL) bring a frame to 309 lines: 29.97 frames/s,
//! a line 108 µs, 69 lines (7.5 ms) of vertical blanking.
//!
//! Exposure is fixed, not automatic: the module's LEDs are its only light, and an
//! automatic exposure free to lengthen up to a frame (33 ms) would smear the moving belt
//! over many pixels. It is capped so the belt at its design speed moves at most half a
//! pixel while a row is exposed (AEC off in COM8, the time in lines in AECH:AEC); the gain
//! stays automatic (AGC).
//!
//! ```text
//! exposure lines = ⌊ blur budget (½ px × 50 µm) / belt speed / line time ⌋
//!                = ⌊ 25 µm / 26 mm/s / 108 µs ⌋ = 8 lines (0.86 ms)
//! ```

use rollfuse_core::device::CAMERA;

/// The OV7725's registers the driver reads or writes, by their datasheet names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Reg {
    /// Product ID, high byte.
    Pid = 0x0A,
    /// Product ID, low byte.
    Ver = 0x0B,
    /// Common control 3: output byte order.
    Com3 = 0x0C,
    /// Common control 4: PLL multiplier (bits 7..6).
    Com4 = 0x0D,
    /// Exposure in lines, high byte.
    Aech = 0x08,
    /// Exposure in lines, low byte.
    Aec = 0x10,
    /// Internal clock prescaler.
    Clkrc = 0x11,
    /// Common control 7: reset, resolution, output format.
    Com7 = 0x12,
    /// Common control 8: automatic exposure (bit 0), white balance (bit 1), gain (bit 2).
    Com8 = 0x13,
    /// Sensor window: horizontal start (high 8 bits).
    Hstart = 0x17,
    /// Sensor window: width / 4.
    Hsize = 0x18,
    /// Sensor window: vertical start (high 8 bits).
    Vstart = 0x19,
    /// Sensor window: height / 2.
    Vsize = 0x1A,
    /// Output width / 4.
    HOutSize = 0x29,
    /// Dummy pixels inserted per row (high bits).
    Exhch = 0x2A,
    /// Dummy pixels inserted per row (low 8 bits).
    Exhcl = 0x2B,
    /// Output height / 2.
    VOutSize = 0x2C,
    /// Dummy lines inserted per frame (low 8 bits).
    Advfl = 0x2D,
    /// Dummy lines inserted per frame (high 8 bits).
    Advfh = 0x2E,
    /// Low bits of the window and output sizes.
    Href = 0x32,
    /// DSP control 4: output selection.
    DspCtrl4 = 0x67,
}

/// The high byte of every OV7725's product ID.
pub const PID_OV77XX: u8 = 0x77;

/// COM7: reset every register to its default.
pub const COM7_RESET: u8 = 0x80;
/// COM7: QVGA resolution (YUV output: the format bits clear).
const COM7_QVGA_YUV: u8 = 0x40;
/// COM3 bit 4, SWAP_YUV: in YUV output, Y before U/V (bytes Y U Y V). Set at reset.
const COM3_SWAP_YUV: u8 = 1 << 4;
/// COM3 bit 3, SWAP_MSB: swaps each output byte's bit order. Never wanted: the pipeline
/// reads Y as sent.
const COM3_SWAP_MSB: u8 = 1 << 3;
/// COM3: bytes Y U Y V, bits in order (the reset value; Linux's ov772x driver and
/// OpenMV's set SWAP_YUV alone for YUYV).
const COM3_YUYV: u8 = COM3_SWAP_YUV;
/// COM4: PLL ×4 (bits 7..6 = 01), the full AEC window, reserved bit 0 kept (0x41 at reset).
const COM4_PLL_X4: u8 = 0x41;
/// CLKRC bit 7 is reserved and set at reset: writes keep it.
const CLKRC_RESERVED: u8 = 1 << 7;
/// CLKRC: pre-scaler 3, PCLK = XCLK × 4 / 8.
const CLKRC_DIV_8: u8 = CLKRC_RESERVED | 0x03;
/// Dummy lines that stretch a 33.3 frames/s frame to 30 frames/s.
const DUMMY_LINES: u16 = 31;
/// DSP_Ctrl4: YUV output from the DSP.
const DSP_CTRL4_YUV: u8 = 0x00;
/// COM8 at reset: fast AGC/AEC, fine AEC, AGC, AWB and AEC on.
const COM8_RESET: u8 = 0x8F;
/// COM8 bit 0: automatic exposure.
const COM8_AEC: u8 = 1 << 0;
/// COM8 bit 2: automatic gain.
const COM8_AGC: u8 = 1 << 2;
/// COM8: exposure held where AECH:AEC put it, everything else as at reset.
const COM8_FIXED_EXPOSURE: u8 = COM8_RESET & !COM8_AEC;
const _: () = assert!(COM8_FIXED_EXPOSURE & COM8_AGC != 0);

/// The belt speed the exposure is capped for: a 16-pixel frame spacing at 30 frames/s
/// (the QEMU run's 26 mm/s rounds it up).
pub const DESIGN_SPEED_UM_S: u32 = 26_000;
/// The most the belt may move while a row is exposed, µm (half a 50 µm pixel).
pub const BLUR_BUDGET_UM: u32 = 25;
/// The frame's line time at the programmed rate, ns (2 × 576 PCLK at 10.67 MHz).
const LINE_NS: u32 = 108_000;
/// Exposure lines: the blur budget's time at the design speed, in whole lines.
const EXPOSURE_LINES: u16 =
    (BLUR_BUDGET_UM as u64 * 1_000_000_000 / DESIGN_SPEED_UM_S as u64 / LINE_NS as u64) as u16;
const _: () = assert!(EXPOSURE_LINES >= 1);

/// Width / 4 and height / 2 as the window and output-size registers take them.
const WIDTH_4: u8 = (CAMERA.width / 4) as u8;
const HEIGHT_2: u8 = (CAMERA.height / 2) as u8;
// The camera's size fits the registers without its low bits (HREF stays 0).
const _: () = assert!(CAMERA.width.is_multiple_of(4) && CAMERA.width / 4 <= 0xFF);
const _: () = assert!(CAMERA.height.is_multiple_of(2) && CAMERA.height / 2 <= 0xFF);
const _: () = assert!(COM3_YUYV & COM3_SWAP_MSB == 0);

/// After the reset, in order: QVGA, YUV output, the clock and frame length for 30
/// frames/s, byte order, the camera's window (the datasheet's QVGA settings: window start
/// 0x3F, 0x03), and the fixed exposure.
pub const SETUP: &[(Reg, u8)] = &[
    (Reg::Com7, COM7_QVGA_YUV),
    (Reg::Com4, COM4_PLL_X4),
    (Reg::Clkrc, CLKRC_DIV_8),
    (Reg::Advfl, DUMMY_LINES.to_le_bytes()[0]),
    (Reg::Advfh, DUMMY_LINES.to_le_bytes()[1]),
    (Reg::DspCtrl4, DSP_CTRL4_YUV),
    (Reg::Com3, COM3_YUYV),
    (Reg::Hstart, 0x3F),
    (Reg::Hsize, WIDTH_4),
    (Reg::Vstart, 0x03),
    (Reg::Vsize, HEIGHT_2),
    (Reg::Href, 0x00),
    (Reg::HOutSize, WIDTH_4),
    (Reg::VOutSize, HEIGHT_2),
    (Reg::Exhch, 0x00),
    (Reg::Exhcl, 0x00),
    (Reg::Com8, COM8_FIXED_EXPOSURE),
    (Reg::Aech, EXPOSURE_LINES.to_be_bytes()[0]),
    (Reg::Aec, EXPOSURE_LINES.to_be_bytes()[1]),
];

/// The sensor's input clock: HSI (64 MHz) / 3 from MCO1.
pub const XCLK_HZ: u32 = 64_000_000 / 3;

/// QVGA's frame in pixel times without dummy pixels or lines (datasheet).
const QVGA_LINE_PIXELS: u32 = 576;
const QVGA_FRAME_LINES: u32 = 278;

/// The frame timing a set of register writes programs, applied to the reset values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Pixel clock, Hz.
    pub pclk_hz: f64,
    /// One line, seconds.
    pub line_s: f64,
    /// Lines a frame, blanking included.
    pub lines: u32,
    /// Frames a second.
    pub frames_per_s: f64,
    /// Vertical blanking (the lines after the window), seconds.
    pub blanking_s: f64,
    /// A row's exposure, seconds; `None` while automatic exposure sets it.
    pub exposure_s: Option<f64>,
}

/// The timing `writes` program from the reset values (COM4 0x41, CLKRC 0x80, no dummy
/// pixels or lines), at input clock `xclk_hz`.
pub fn timing(writes: &[(Reg, u8)], xclk_hz: u32) -> Timing {
    let last = |reg: Reg, reset: u8| {
        writes
            .iter()
            .rev()
            .find(|(r, _)| *r == reg)
            .map_or(reset, |&(_, v)| v)
    };
    let pll = match last(Reg::Com4, 0x41) >> 6 {
        0 => 1,
        1 => 4,
        2 => 6,
        _ => 8,
    };
    let prescale = u32::from(last(Reg::Clkrc, 0x80) & 0x3F) + 1;
    let pclk_hz = f64::from(xclk_hz) * f64::from(pll) / f64::from(2 * prescale);
    let dummy_pixels = u32::from(u16::from_le_bytes([
        last(Reg::Exhcl, 0),
        last(Reg::Exhch, 0),
    ]));
    let dummy_lines = u32::from(u16::from_le_bytes([
        last(Reg::Advfl, 0),
        last(Reg::Advfh, 0),
    ]));
    let lines = QVGA_FRAME_LINES + dummy_lines;
    // YUV: two pixel clocks a pixel.
    let line_s = f64::from(2 * (QVGA_LINE_PIXELS + dummy_pixels)) / pclk_hz;
    let window_lines = 2 * u32::from(last(Reg::Vsize, HEIGHT_2));
    let exposure_lines = u16::from_be_bytes([last(Reg::Aech, 0), last(Reg::Aec, 0)]);
    let automatic = last(Reg::Com8, COM8_RESET) & COM8_AEC != 0;
    Timing {
        pclk_hz,
        line_s,
        lines,
        frames_per_s: 1.0 / (line_s * f64::from(lines)),
        blanking_s: line_s * f64::from(lines.saturating_sub(window_lines)),
        exposure_s: (!automatic).then(|| line_s * f64::from(exposure_lines)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn written(reg: Reg) -> u8 {
        SETUP.iter().rev().find(|(r, _)| *r == reg).unwrap().1
    }

    #[test]
    fn the_set_up_programs_thirty_frames_a_second() {
        let t = timing(SETUP, XCLK_HZ);
        assert!((t.pclk_hz - 10_666_666.7).abs() < 1.0, "{t:?}");
        assert_eq!(t.lines, 309);
        assert!((t.frames_per_s - 30.0).abs() < 0.05, "{t:?}");
        assert!((t.blanking_s - 7.45e-3).abs() < 0.01e-3, "{t:?}");
        // CLKRC 0x81 alone, the firmware's first set-up, ran the sensor at 66.6 frames/s.
        let first = timing(&[(Reg::Clkrc, 0x81)], XCLK_HZ);
        assert!((first.frames_per_s - 66.6).abs() < 0.1, "{first:?}");
    }

    #[test]
    fn the_set_up_sends_yuyv_in_bit_order_and_keeps_reserved_bits() {
        assert_eq!(written(Reg::Com3), 0x10, "SWAP_YUV alone");
        assert_eq!(written(Reg::Com7) & 0x03, 0x00, "YUV output");
        assert_eq!(written(Reg::Clkrc) & 0x80, 0x80, "CLKRC bit 7 reserved");
        assert_eq!(written(Reg::Com4) & 0x01, 0x01, "COM4 bit 0 reserved");
        // The register reset comes first, never from the table.
        assert!(
            SETUP
                .iter()
                .all(|&(r, v)| r != Reg::Com7 || v & COM7_RESET == 0)
        );
    }

    #[test]
    fn the_exposure_is_fixed_short_enough_for_the_belt_with_the_gain_automatic() {
        let t = timing(SETUP, XCLK_HZ);
        // The constant the exposure is computed from is the programmed line time.
        assert!((t.line_s - f64::from(LINE_NS) * 1e-9).abs() < 1e-9, "{t:?}");
        let exposure = t.exposure_s.expect("automatic exposure left on");
        let blur_um = exposure * f64::from(DESIGN_SPEED_UM_S);
        assert!(blur_um <= f64::from(BLUR_BUDGET_UM), "{blur_um} µm of blur");
        // Not needlessly short: one more line would break the budget.
        let longer = (exposure + t.line_s) * f64::from(DESIGN_SPEED_UM_S);
        assert!(longer > f64::from(BLUR_BUDGET_UM), "{exposure} s");
        assert_eq!(
            written(Reg::Com8),
            0x8E,
            "AEC off, AGC, AWB and the rest as at reset"
        );
        assert_ne!(written(Reg::Com8) & COM8_AGC, 0);
        // Without the writes, exposure is the sensor's own choice.
        assert_eq!(timing(&[], XCLK_HZ).exposure_s, None);
    }

    #[test]
    fn the_window_is_the_cameras_size() {
        // HREF holds the sizes' low bits: HSIZE's two in bits 1..0, VSIZE's one in bit 2.
        let href = usize::from(written(Reg::Href));
        let width = 4 * usize::from(written(Reg::Hsize)) + (href & 3);
        let height = 2 * usize::from(written(Reg::Vsize)) + ((href >> 2) & 1);
        assert_eq!((width, height), (CAMERA.width, CAMERA.height));
        assert_eq!(written(Reg::HOutSize), written(Reg::Hsize));
        assert_eq!(written(Reg::VOutSize), written(Reg::Vsize));
    }
}
