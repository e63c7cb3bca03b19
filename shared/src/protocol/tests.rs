extern crate std;

use super::*;
use proptest::prelude::*;
use std::vec::Vec;

fn encoded<T: Serialize + Limits>(seq: u32, body: &T) -> Vec<u8> {
    let mut buf = [0u8; MAX_MESSAGE];
    let n = encode(seq, body, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn sample_messages(pixels: &[u8], chunk: &[u8]) -> Vec<DeviceMessage<'static>> {
    let pixels: &'static [u8] = Vec::leak(pixels.to_vec());
    let chunk: &'static [u8] = Vec::leak(chunk.to_vec());
    std::vec![
        DeviceMessage::Info(DeviceInfo {
            firmware: [0, 1, 0],
            sensor_width: 320,
            sensor_height: 240,
            pixel_format: PixelFormat::Yuyv,
            config: DeviceConfig::default(),
            max_tile_bytes: MAX_TILE_BYTES as u32,
        }),
        DeviceMessage::Ack { command_seq: 7 },
        DeviceMessage::Nak {
            command_seq: u32::MAX,
            reason: NakReason::Levels,
        },
        DeviceMessage::Status(StatusCounters {
            frames_captured: 1 << 20,
            tiles_dropped: 3,
            streaming: true,
            fusion_cycles_worst: u32::MAX,
            fusion_cycles_mean: 1_560_000,
            ..Default::default()
        }),
        DeviceMessage::Tile(Tile {
            index: 12345,
            width: 10,
            height: (pixels.len() / 10) as u16,
            observations: 4,
            pixels: &pixels[..pixels.len() / 10 * 10],
        }),
        DeviceMessage::RawChunk(RawChunk {
            frame: 1,
            offset: 100,
            total: 100 + chunk.len() as u32,
            data: chunk,
        }),
        DeviceMessage::Log("camera ready"),
    ]
}

#[test]
fn every_message_round_trips() {
    let pixels: Vec<u8> = (0..160 * 16).map(|i| i as u8).collect();
    for (k, msg) in sample_messages(&pixels, &[9; MAX_CHUNK]).iter().enumerate() {
        let bytes = encoded(k as u32, msg);
        let (h, back): (Header, DeviceMessage) = decode(&bytes).unwrap();
        assert_eq!(h.seq, k as u32);
        assert_eq!(&back, msg);
    }
    let commands = [
        Command::Hello,
        Command::Configure(DeviceConfig::default()),
        Command::Leds(LedDuty::ALL_ON),
        Command::Roller(RollerCommand::Start { speed_um_s: 20_000 }),
        Command::Roller(RollerCommand::Stop),
        Command::StreamStart,
        Command::StreamStop,
        Command::CaptureRaw { frames: 2 },
        Command::Status,
    ];
    for c in commands {
        let bytes = encoded(u32::MAX, &c);
        assert_eq!(decode::<Command>(&bytes), Ok((header(u32::MAX), c)));
    }
}

fn header(seq: u32) -> Header {
    Header {
        version: PROTOCOL_VERSION,
        seq,
    }
}

#[test]
fn the_largest_messages_fit_and_one_byte_more_is_refused() {
    let pixels = std::vec![200u8; MAX_TILE_BYTES];
    let tile = |pixels| {
        DeviceMessage::Tile(Tile {
            index: u32::MAX,
            width: u16::MAX,
            height: 0,
            observations: u8::MAX,
            pixels,
        })
    };
    // Width × height must match the pixels: 16 000 = 640 × 25.
    let full = DeviceMessage::Tile(Tile {
        index: u32::MAX,
        width: 640,
        height: 25,
        observations: u8::MAX,
        pixels: &pixels,
    });
    let bytes = encoded(u32::MAX, &full);
    assert!(bytes.len() <= MAX_MESSAGE);
    assert_eq!(decode::<DeviceMessage>(&bytes).unwrap().1, full);
    let mut buf = [0u8; MAX_MESSAGE];
    assert_eq!(
        encode(0, &tile(&pixels[..5]), &mut buf),
        Err(EncodeError::Limit("tile pixel count"))
    );
    // An empty tile (no strip can take one), whatever its sides.
    for (width, height) in [(0, 0), (0, 5), (1, 0)] {
        let empty = DeviceMessage::Tile(Tile {
            index: 0,
            width,
            height,
            observations: 1,
            pixels: &[],
        });
        assert_eq!(
            encode(0, &empty, &mut buf),
            Err(EncodeError::Limit("empty tile")),
            "{width}×{height}"
        );
    }
    let over = std::vec![0u8; MAX_TILE_BYTES + 1];
    let big = DeviceMessage::Tile(Tile {
        index: 0,
        width: (MAX_TILE_BYTES + 1) as u16,
        height: 1,
        observations: 1,
        pixels: &over,
    });
    assert_eq!(
        encode(0, &big, &mut std::vec![0u8; 2 * MAX_MESSAGE]),
        Err(EncodeError::Limit("tile size"))
    );
    let long = "x".repeat(MAX_LOG + 1);
    assert_eq!(
        encode(0, &DeviceMessage::Log(&long), &mut buf),
        Err(EncodeError::Limit("log line length"))
    );
    let chunk = std::vec![0u8; MAX_CHUNK + 1];
    let raw = DeviceMessage::RawChunk(RawChunk {
        frame: 0,
        offset: 0,
        total: u32::MAX,
        data: &chunk,
    });
    assert_eq!(
        encode(0, &raw, &mut buf),
        Err(EncodeError::Limit("raw chunk size"))
    );
    assert_eq!(
        encode(0, &Command::Hello, &mut [0u8; 3]),
        Err(EncodeError::BufferTooSmall)
    );
}

/// A message whose CRC is right but whose inside lies: the limits are checked after
/// decoding, so a sender that skipped them is still caught.
#[test]
fn lying_lengths_with_a_good_crc_are_refused() {
    let mut body = Vec::new();
    body.extend_from_slice(&postcard::to_allocvec(&header(5)).unwrap());
    // Tile variant (index 4), index 1, width 3, height 3, observations 1, then 4 bytes.
    body.extend_from_slice(&[4, 1, 3, 3, 1, 4, 1, 2, 3, 4]);
    let crc = CRC.checksum(&body).to_le_bytes();
    body.extend_from_slice(&crc);
    assert_eq!(
        decode::<DeviceMessage>(&body),
        Err(DecodeError::Limit("tile pixel count"))
    );
    // A length prefix pointing past the end.
    let mut body = postcard::to_allocvec(&header(5)).unwrap();
    body.extend_from_slice(&[6, 0x7f, b'h', b'i']);
    let crc = CRC.checksum(&body).to_le_bytes();
    body.extend_from_slice(&crc);
    assert_eq!(decode::<DeviceMessage>(&body), Err(DecodeError::Malformed));
}

#[test]
fn other_versions_and_trailing_bytes_are_refused() {
    let other = PROTOCOL_VERSION + 1;
    let mut body = postcard::to_allocvec(&Header {
        version: other,
        seq: 1,
    })
    .unwrap();
    body.extend_from_slice(&postcard::to_allocvec(&Command::Hello).unwrap());
    let crc = CRC.checksum(&body).to_le_bytes();
    body.extend_from_slice(&crc);
    assert_eq!(decode::<Command>(&body), Err(DecodeError::Version(other)));

    let mut body = postcard::to_allocvec(&header(1)).unwrap();
    body.extend_from_slice(&postcard::to_allocvec(&Command::Hello).unwrap());
    body.push(0);
    let crc = CRC.checksum(&body).to_le_bytes();
    body.extend_from_slice(&crc);
    assert_eq!(decode::<Command>(&body), Err(DecodeError::Malformed));
}

#[test]
fn sequence_gaps_repeats_and_wraparound_are_told_apart() {
    let mut t = SeqTracker::new();
    assert_eq!(t.observe(u32::MAX - 1), SeqEvent::InOrder);
    assert_eq!(t.observe(u32::MAX), SeqEvent::InOrder);
    assert_eq!(t.observe(0), SeqEvent::InOrder);
    assert_eq!(t.observe(3), SeqEvent::Gap { missing: 2 });
    assert_eq!(t.observe(3), SeqEvent::Repeat);
    assert_eq!(t.observe(1), SeqEvent::Repeat);
    assert_eq!(t.observe(4), SeqEvent::InOrder);
    assert_eq!(
        t.observe(4 + 1 + MAX_GAP),
        SeqEvent::Gap { missing: MAX_GAP }
    );
}

/// One stray message far ahead (or a crafted one) does not make the good messages after
/// it look old; a sender that restarts its numbering is followed from its second message.
#[test]
fn a_stray_number_is_passed_over_and_a_restart_is_followed() {
    let mut t = SeqTracker::new();
    for seq in 0..13 {
        assert_eq!(t.observe(seq), SeqEvent::InOrder);
    }
    assert_eq!(t.observe(100_000), SeqEvent::FarAhead);
    for seq in 13..20 {
        assert_eq!(t.observe(seq), SeqEvent::InOrder, "{seq}");
    }
    // A reset: back to 0, then on from there.
    assert_eq!(t.observe(0), SeqEvent::Repeat);
    assert_eq!(t.observe(1), SeqEvent::Renumbered);
    assert_eq!(t.observe(2), SeqEvent::InOrder);
    // Numbers going back one by one (a recording played backwards) never renumber.
    let mut back = SeqTracker::new();
    assert_eq!(back.observe(50), SeqEvent::InOrder);
    for seq in (0..50).rev() {
        assert_eq!(back.observe(seq), SeqEvent::Repeat, "{seq}");
    }
    // A stray whose next number then arrives: a jump that holds is followed.
    let mut jump = SeqTracker::new();
    jump.observe(7);
    assert_eq!(jump.observe(5_000), SeqEvent::FarAhead);
    assert_eq!(jump.observe(5_001), SeqEvent::Renumbered);
}

/// Cases per property: 2000 in `cargo test`; set `ROLLFUSE_FUZZ_CASES` for a long run
/// (docs/device.md gives the command and the last result).
fn cases() -> u32 {
    std::env::var("ROLLFUSE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2000)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    /// Flipped bits never pass as a different message: the CRC-32 catches them (any 1–3
    /// flips always; more with probability 1 − 2⁻³²).
    #[test]
    fn flipped_bits_are_caught(
        which in 0usize..7,
        flips in proptest::collection::vec(any::<usize>(), 1..4),
        data in proptest::collection::vec(any::<u8>(), 10..400),
    ) {
        let msgs = sample_messages(&data, &data);
        let msg = &msgs[which];
        let mut bytes = encoded(9, msg);
        let mut flipped = std::collections::BTreeSet::new();
        for f in flips {
            let bit = f % (bytes.len() * 8);
            if flipped.insert(bit) {
                bytes[bit / 8] ^= 1 << (bit % 8);
            }
        }
        let res = decode::<DeviceMessage>(&bytes);
        prop_assert!(res.is_err(), "{:?}", res);
    }

    /// Any prefix is refused, and so is any random junk, without a panic.
    #[test]
    fn truncations_and_junk_are_refused(
        which in 0usize..7,
        cut in any::<usize>(),
        junk in proptest::collection::vec(any::<u8>(), 0..600),
    ) {
        let data: Vec<u8> = (0..200u8).collect();
        let msgs = sample_messages(&data, &data);
        let bytes = encoded(1, &msgs[which]);
        let cut = cut % bytes.len();
        prop_assert!(decode::<DeviceMessage>(&bytes[..cut]).is_err());
        // Junk may decode only if its last four bytes happen to be its CRC.
        let _ = decode::<DeviceMessage>(&junk);
        let _ = decode::<Command>(&junk);
    }
}
