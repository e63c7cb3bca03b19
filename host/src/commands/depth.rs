//! `rollfuse depth` and `rollfuse calibrate`: height maps from RGB tactile images, and the
//! light file they need.

use super::check_writable;
use anyhow::{Context, bail};
use rollfuse::depth::calibrate::{Circle, calibrate};
use rollfuse::depth::lights::Lights;
use rollfuse::depth::{output, reconstruct};
use rollfuse::files::{Batch, NewFolder};
use rollfuse::image::{PixelLimit, Planes};
use std::path::{Path, PathBuf};

/// Arguments of `rollfuse depth`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The RGB tactile image (a single frame or a fused one).
    pub image: PathBuf,
    /// The light file (scale, LED directions, gains); `rollfuse calibrate` writes one.
    #[arg(long)]
    pub lights: PathBuf,
    /// The no-contact frame (else a smooth estimate from the image).
    #[arg(long)]
    pub background: Option<PathBuf>,
    /// Output stem: writes STEM.npy (float32 mm) and STEM.png (colour map with scale bar);
    /// `--out d.png` is the stem `d` (an extension of these outputs is dropped).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write STEM.ply, a point cloud in mm.
    #[arg(long)]
    pub ply: bool,
}

/// The extensions `rollfuse depth` writes.
const DEPTH_EXTENSIONS: [&str; 3] = ["npy", "png", "ply"];

/// `STEM` + `.ext`, keeping any dots in the stem; a stem that ends in one of the outputs'
/// extensions loses it first.
fn with_ext(stem: &Path, ext: &str) -> PathBuf {
    let own = stem
        .extension()
        .is_some_and(|e| DEPTH_EXTENSIONS.iter().any(|d| e == *d));
    let stem = if own {
        stem.with_extension("")
    } else {
        stem.to_path_buf()
    };
    let mut s = stem.into_os_string();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

/// The image and, if one is given, the background image, each read within `limit`.
fn load_with_background(
    image: &Path,
    background: Option<&Path>,
    limit: PixelLimit,
) -> anyhow::Result<(Planes, Option<Planes>)> {
    let image = Planes::load(image, limit)?;
    let background = background.map(|b| Planes::load(b, limit)).transpose()?;
    Ok((image, background))
}

/// Runs `rollfuse depth`, reading images within `limit`.
pub fn run(args: Args, limit: PixelLimit) -> anyhow::Result<()> {
    let outputs: Vec<PathBuf> = DEPTH_EXTENSIONS[..2]
        .iter()
        .chain(args.ply.then_some(&DEPTH_EXTENSIONS[2]))
        .map(|e| with_ext(&args.out, e))
        .collect();
    let mut inputs = vec![
        ("input image", args.image.as_path()),
        ("light file", &args.lights),
    ];
    inputs.extend(args.background.as_deref().map(|b| ("background", b)));
    let targets: Vec<&Path> = outputs.iter().map(PathBuf::as_path).collect();
    rollfuse::files::refuse_overwriting(&targets, &inputs)?;
    for o in &outputs {
        check_writable(o)?;
    }
    let _folder = NewFolder::for_file(&outputs[0])?;
    let lights = Lights::load(&args.lights)?;
    let (image, background) = load_with_background(&args.image, args.background.as_deref(), limit)?;
    let started = std::time::Instant::now();
    let depth = reconstruct(&image, background.as_ref(), &lights)
        .with_context(|| format!("depth of {}", args.image.display()))?;
    let took = started.elapsed().as_secs_f64();
    let mut batch = Batch::new();
    output::write_npy(&depth, &mut batch, &outputs[0])?;
    output::write_png(&depth, &mut batch, &outputs[1])?;
    if args.ply {
        output::write_ply(&depth, &mut batch, &outputs[2])?;
    }
    batch.commit()?;
    let peak = depth.height_mm.iter().copied().fold(0f32, f32::max);
    let contact = depth.contact.iter().filter(|&&c| c).count();
    println!(
        "{}×{}: peak height {peak:.3} mm, contact {:.1} mm² ({contact} px); took {took:.4} s → {}",
        depth.width,
        depth.height,
        contact as f64 * lights.mm_per_px * lights.mm_per_px,
        outputs
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// Arguments of `rollfuse calibrate`.
#[derive(Debug, clap::Args)]
pub struct CalibrateArgs {
    /// RGB image of a ball pressed into the gel.
    pub image: PathBuf,
    /// The ball's radius, mm.
    #[arg(long)]
    pub radius_mm: f64,
    /// The image scale, mm per pixel.
    #[arg(long)]
    pub mm_per_px: f64,
    /// The no-contact frame (else a smooth estimate from the image).
    #[arg(long)]
    pub background: Option<PathBuf>,
    /// The contact disc, pixels, instead of finding it: `x,y,r`.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub circle: Option<Vec<f64>>,
    /// The light file to write.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `rollfuse calibrate`, reading images within `limit`.
pub fn calibrate_run(args: CalibrateArgs, limit: PixelLimit) -> anyhow::Result<()> {
    let mut inputs = vec![("input image", args.image.as_path())];
    inputs.extend(args.background.as_deref().map(|b| ("background", b)));
    rollfuse::files::refuse_overwriting(&[&args.out], &inputs)?;
    check_writable(&args.out)?;
    let _folder = NewFolder::for_file(&args.out)?;
    let circle = match args.circle.as_deref() {
        None => None,
        Some(&[x, y, r]) if x.is_finite() && y.is_finite() && r.is_finite() && r > 0.0 => {
            Some(Circle { x, y, r })
        }
        Some(c) => bail!("--circle must be x,y,r with r > 0, got {c:?}"),
    };
    let (image, background) = load_with_background(&args.image, args.background.as_deref(), limit)?;
    let (lights, disc) = calibrate(
        &image,
        background.as_ref(),
        args.radius_mm,
        args.mm_per_px,
        circle,
    )
    .with_context(|| format!("calibrating from {}", args.image.display()))?;
    lights.save(&args.out)?;
    println!(
        "contact disc at ({:.1}, {:.1}), radius {:.1} px; light matrix condition number {:.2} → {}",
        disc.x,
        disc.y,
        disc.r,
        lights.condition(),
        args.out.display()
    );
    for (name, d, g) in [
        ("red", lights.red, lights.gains[0]),
        ("green", lights.green, lights.gains[1]),
        ("blue", lights.blue, lights.gains[2]),
    ] {
        let elevation = d[2].asin().to_degrees();
        let azimuth = d[1].atan2(d[0]).to_degrees();
        println!(
            "  {name:<5} [{:+.4}, {:+.4}, {:+.4}]  elevation {elevation:.1}°, azimuth {azimuth:.1}°, gain {g:.3}",
            d[0], d[1], d[2]
        );
    }
    Ok(())
}
