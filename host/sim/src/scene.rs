//! The scene file: what is under the roller, the sensor, the lights, and which effects to
//! simulate. TOML, every field documented in `docs/simulator.md`; unknown fields are
//! refused, and every value is checked with an error that names its field.

use crate::Error;
use rollfuse_io::invalid;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: usize = 4096;
/// Largest accepted number of frames in one simulation.
pub const MAX_FRAMES: usize = 10_000;
/// Largest accepted ground-truth strip (the belt area all frames see), in pixels.
pub const MAX_STRIP_PIXELS: usize = 1 << 26;

/// Checks a textile's fields: a known fabric, a bounded number of defects, a sane scale.
fn validate_textile(fabric: &str, defects: usize, scale: f64) -> Result<(), Error> {
    if super::textile::fabric(fabric).is_none() {
        let names: Vec<&str> = super::textile::FABRICS.iter().map(|f| f.name).collect();
        invalid!(
            "object.fabric must be one of {}, got {fabric:?}",
            names.join(", ")
        );
    }
    if defects > MAX_DEFECTS {
        invalid!("object.defects must be at most {MAX_DEFECTS}, got {defects}");
    }
    if !(0.5..=2.0).contains(&scale) {
        invalid!("object.scale must be in 0.5..=2, got {scale}");
    }
    Ok(())
}

/// Most defects one textile scene places.
pub const MAX_DEFECTS: usize = 100;

/// A complete scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// A short name for reports (defaults to the file's stem).
    #[serde(default)]
    pub name: String,
    /// Seed of every random effect (noise, jitter).
    #[serde(default)]
    pub seed: u64,
    /// The effects to compute, each a separate stage; unlisted effects cost nothing.
    pub effects: Vec<Effect>,
    /// What lies on the belt.
    pub object: Object,
    /// The sensor's geometry and motion.
    pub sensor: Sensor,
    /// The three LEDs (used by `gray` and `rgb` shading).
    #[serde(default)]
    pub lights: Lights,
    /// Strengths of the optional effects.
    #[serde(default)]
    pub params: EffectParams,
}

/// One simulation stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Effect {
    /// Indentation into the curved gel: deepest under the roller's apex, shallower toward
    /// the image edges. Without it the gel is pressed flat at the apex depth everywhere.
    Contact,
    /// Elastomer smoothing of the indentation (Gaussian, width set by gel thickness).
    Gel,
    /// Monochrome Lambertian shading under all three LEDs (the luma of `rgb`).
    Gray,
    /// One LED per colour channel, Lambertian (for photometric stereo).
    Rgb,
    /// Blur that grows with distance from the focal line.
    Defocus,
    /// Sensor read and shot noise, seeded.
    Noise,
    /// Random errors in each frame's belt position.
    Jitter,
    /// Uneven illumination (vignetting and a gradient).
    Background,
    /// A belt whose speed varies: each frame's travel differs from `frame_spacing_mm` by
    /// up to `speed_jitter` of it, at random. The motion system counts the steps, so the
    /// commanded positions follow it (unlike `jitter`).
    Speed,
    /// A belt that wanders sideways: each frame's sideways offset moves from the last by up
    /// to `wander_px` columns, at random (a walk the motion system does not see).
    Wander,
}

impl Effect {
    /// Every effect, in stage order.
    pub const ALL: [Effect; 10] = [
        Effect::Speed,
        Effect::Jitter,
        Effect::Wander,
        Effect::Contact,
        Effect::Gel,
        Effect::Gray,
        Effect::Rgb,
        Effect::Defocus,
        Effect::Background,
        Effect::Noise,
    ];

    /// The name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Contact => "contact",
            Effect::Gel => "gel",
            Effect::Gray => "gray",
            Effect::Rgb => "rgb",
            Effect::Defocus => "defocus",
            Effect::Noise => "noise",
            Effect::Jitter => "jitter",
            Effect::Speed => "speed",
            Effect::Wander => "wander",
            Effect::Background => "background",
        }
    }
}

/// The object on the belt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Object {
    /// A word in raised strokes (built-in 5×7 stroke font, A–Z, 0–9, space).
    Letters {
        /// The word.
        text: String,
        /// Stroke height, mm.
        #[serde(default = "one_mm")]
        height_mm: f64,
    },
    /// The paper's standardized sample: a matrix of round dots raised `height_mm`.
    Dots {
        /// Raise, mm.
        #[serde(default = "one_mm")]
        height_mm: f64,
        /// Centre-to-centre spacing, mm.
        #[serde(default = "two_mm")]
        pitch_mm: f64,
        /// Dot diameter, mm.
        #[serde(default = "one_mm")]
        size_mm: f64,
    },
    /// A matrix of short straight bars.
    Lines {
        /// Raise, mm.
        #[serde(default = "one_mm")]
        height_mm: f64,
        /// Centre-to-centre spacing, mm.
        #[serde(default = "two_mm")]
        pitch_mm: f64,
        /// Bar width, mm.
        #[serde(default = "half_mm")]
        size_mm: f64,
    },
    /// A matrix of arcs.
    Curves {
        /// Raise, mm.
        #[serde(default = "one_mm")]
        height_mm: f64,
        /// Centre-to-centre spacing, mm.
        #[serde(default = "two_mm")]
        pitch_mm: f64,
        /// Stroke width, mm.
        #[serde(default = "half_mm")]
        size_mm: f64,
    },
    /// Three spheres of `diameter_mm` pressed side by side (the depth scene); each is a
    /// region with its own mask.
    Spheres {
        /// Sphere diameter, mm.
        #[serde(default = "four_mm")]
        diameter_mm: f64,
    },
    /// Woven fabric: three weave patterns side by side and three defects.
    Fabric {
        /// Yarn thickness (height of a crossing), mm.
        #[serde(default = "yarn_mm")]
        yarn_mm: f64,
        /// Yarn spacing, mm.
        #[serde(default = "one_mm")]
        pitch_mm: f64,
    },
    /// A machine screw lying along the belt.
    Screw {
        /// Major diameter, mm.
        #[serde(default = "four_mm")]
        diameter_mm: f64,
        /// Thread pitch, mm.
        #[serde(default = "thread_mm")]
        pitch_mm: f64,
    },
    /// A paper clip (bent round wire).
    Paperclip {
        /// Wire diameter, mm.
        #[serde(default = "wire_mm")]
        wire_mm: f64,
    },
    /// One fabric of the detector's 17 classes (`docs/simulator.md`, Textiles) with
    /// `defects` holes, snags and slubs placed at random from the scene's seed; their
    /// boxes are written to `truth/defects.json`.
    Textile {
        /// The fabric's name, one of `rollfuse::sim::textile::FABRICS`.
        fabric: String,
        /// How many defects to place.
        #[serde(default = "three")]
        defects: usize,
        /// Yarn size and spacing as a multiple of the fabric's own.
        #[serde(default = "unit")]
        scale: f64,
    },
    /// Height-map primitives placed by hand, in belt millimetres (x across the belt from
    /// the image's left edge, y along the belt on the object's canvas; see
    /// `docs/simulator.md`, Coordinates).
    Primitives {
        /// The shapes; heights add where they overlap.
        shapes: Vec<Shape>,
    },
}

/// One primitive of [`Object::Primitives`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "lowercase", deny_unknown_fields)]
pub enum Shape {
    /// A spherical cap: a sphere of `radius_mm` whose top is `height_mm` above the belt.
    Sphere {
        /// Centre across the belt, mm.
        x_mm: f64,
        /// Centre along the belt, mm.
        y_mm: f64,
        /// Sphere radius, mm.
        radius_mm: f64,
        /// Height of the top, mm (default: the radius — a half sphere).
        height_mm: Option<f64>,
        /// Region name: a mask is written for it.
        region: Option<String>,
    },
    /// A flat-topped box.
    Box {
        /// Centre across the belt, mm.
        x_mm: f64,
        /// Centre along the belt, mm.
        y_mm: f64,
        /// Size across the belt, mm.
        width_mm: f64,
        /// Size along the belt, mm.
        length_mm: f64,
        /// Height, mm.
        height_mm: f64,
        /// Region name: a mask is written for it.
        region: Option<String>,
    },
}

fn one_mm() -> f64 {
    1.0
}
fn two_mm() -> f64 {
    2.0
}
fn half_mm() -> f64 {
    0.5
}
fn four_mm() -> f64 {
    4.0
}
fn three() -> usize {
    3
}
fn unit() -> f64 {
    1.0
}
fn yarn_mm() -> f64 {
    0.3
}
fn thread_mm() -> f64 {
    0.7
}
fn wire_mm() -> f64 {
    0.9
}

/// The sensor's geometry and its motion along the belt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensor {
    /// Radius of the roller's outer (gel) surface, mm.
    pub roller_radius_mm: f64,
    /// Gel thickness, mm: the deepest an object can press in.
    pub gel_thickness_mm: f64,
    /// Belt millimetres per image pixel.
    pub mm_per_px: f64,
    /// Image width in pixels (across the belt).
    pub width_px: usize,
    /// Image height in pixels (along the belt; the roller's apex is the middle row).
    pub height_px: usize,
    /// How far the tallest feature presses into the gel at the apex, mm.
    pub press_depth_mm: f64,
    /// Belt travel between frames, mm.
    pub frame_spacing_mm: f64,
    /// Number of frames.
    pub frames: usize,
    /// The row in focus (default: the apex, the middle row).
    pub focal_row: Option<usize>,
}

impl Sensor {
    /// The roller's geometry as full-resolution fusion needs it: the apex is the middle row.
    pub fn roller_geometry(&self) -> rollfuse_fullres::window::Geometry {
        rollfuse_fullres::window::Geometry {
            roller_radius_mm: self.roller_radius_mm,
            press_depth_mm: self.press_depth_mm,
            mm_per_px: self.mm_per_px,
            apex_row: self.height_px as f64 / 2.0,
        }
    }
}

/// Light directions: unit vectors in image coordinates (x along columns to the right, y
/// along rows downward, z out of the gel toward the camera), from the gel toward the LED.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Lights {
    /// The red LED.
    pub red: [f64; 3],
    /// The green LED.
    pub green: [f64; 3],
    /// The blue LED.
    pub blue: [f64; 3],
}

impl Lights {
    /// The direction of an LED at `azimuth_deg` around the camera, `elevation_deg` above
    /// the gel plane.
    pub fn led(azimuth_deg: f64, elevation_deg: f64) -> [f64; 3] {
        let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()]
    }
}

impl Default for Lights {
    /// Three LEDs at 120° around the camera, 35° above the gel plane.
    fn default() -> Self {
        Self {
            red: Self::led(90.0, 35.0),
            green: Self::led(210.0, 35.0),
            blue: Self::led(330.0, 35.0),
        }
    }
}

/// Strengths of the optional effects; each is used only if its effect is listed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EffectParams {
    /// `gel`: smoothing σ as a fraction of the gel thickness.
    pub gel_sigma_per_thickness: f64,
    /// `defocus`: blur σ, pixels, at the row farthest from the focal line.
    pub defocus_sigma_px: f64,
    /// `noise`: read noise σ, gray levels.
    pub read_noise: f64,
    /// `noise`: shot noise variance per gray level of signal.
    pub shot_noise: f64,
    /// `jitter`: largest belt-position error per frame, pixels.
    pub jitter_px: f64,
    /// `speed`: largest relative change of a frame's travel (0.25: ±25 %).
    pub speed_jitter: f64,
    /// `wander`: largest sideways move of the belt from one frame to the next, pixels.
    pub wander_px: f64,
    /// `background`: relative brightness loss at the image corners.
    pub vignetting: f64,
    /// `background`: relative brightness change from the left edge to the right.
    pub gradient: f64,
}

impl Default for EffectParams {
    fn default() -> Self {
        Self {
            gel_sigma_per_thickness: 0.1,
            defocus_sigma_px: 2.0,
            read_noise: 2.0,
            shot_noise: 0.05,
            jitter_px: 2.0,
            speed_jitter: 0.25,
            wander_px: 0.5,
            vignetting: 0.25,
            gradient: 0.1,
        }
    }
}

impl Scene {
    /// Reads and checks a scene file; the scene's name defaults to the file's stem.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Read {
            what: "scene file",
            path: path.to_path_buf(),
            source,
        })?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene");
        Self::parse(&text, stem)
            .map_err(|e| e.within(format_args!("in scene file {}", path.display())))
    }

    /// Parses and checks a scene from TOML text.
    pub fn parse(text: &str, default_name: &str) -> Result<Self, Error> {
        let mut scene: Scene =
            toml::from_str(text).map_err(|e| Error::Invalid(e.to_string().trim_end().into()))?;
        if scene.name.is_empty() {
            scene.name = default_name.to_string();
        }
        scene.validate()?;
        Ok(scene)
    }

    /// Whether the scene lists `effect`.
    pub fn has(&self, effect: Effect) -> bool {
        self.effects.contains(&effect)
    }

    /// Checks every value, naming the field of the first bad one.
    pub fn validate(&self) -> Result<(), Error> {
        let s = &self.sensor;
        positive("sensor.roller_radius_mm", s.roller_radius_mm)?;
        positive("sensor.gel_thickness_mm", s.gel_thickness_mm)?;
        positive("sensor.mm_per_px", s.mm_per_px)?;
        non_negative("sensor.press_depth_mm", s.press_depth_mm)?;
        non_negative("sensor.frame_spacing_mm", s.frame_spacing_mm)?;
        for (field, v) in [
            ("sensor.width_px", s.width_px),
            ("sensor.height_px", s.height_px),
        ] {
            if !(8..=MAX_IMAGE_SIDE).contains(&v) {
                invalid!("{field} must be 8..={MAX_IMAGE_SIDE} pixels, got {v}");
            }
        }
        if !(1..=MAX_FRAMES).contains(&s.frames) {
            invalid!("sensor.frames must be 1..={MAX_FRAMES}, got {}", s.frames);
        }
        if let Some(row) = s.focal_row
            && row >= s.height_px
        {
            invalid!(
                "sensor.focal_row must be below sensor.height_px ({}), got {row}",
                s.height_px
            );
        }
        if s.roller_radius_mm * 2.0 < s.height_px as f64 * s.mm_per_px * 0.5 {
            invalid!(
                "sensor.roller_radius_mm ({}) is too small for the field of view ({} mm along the belt)",
                s.roller_radius_mm,
                s.height_px as f64 * s.mm_per_px
            );
        }
        // The belt strip every frame sees, in pixels: bounded so the ground truth fits in memory.
        let speed = if self.has(Effect::Speed) {
            1.0 + self.params.speed_jitter
        } else {
            1.0
        };
        let travel_px = (s.frames - 1) as f64 * s.frame_spacing_mm * speed / s.mm_per_px;
        let strip_px = (travel_px + s.height_px as f64 * 2.0 + 2.0 * self.params.jitter_px)
            * s.width_px as f64;
        if strip_px.is_nan() || strip_px > MAX_STRIP_PIXELS as f64 {
            invalid!(
                "sensor.frames × sensor.frame_spacing_mm / sensor.mm_per_px: the belt strip would be {:.0} pixels, more than {MAX_STRIP_PIXELS}",
                strip_px
            );
        }
        if self.has(Effect::Gray) && self.has(Effect::Rgb) {
            invalid!("effects: list `gray` or `rgb`, not both");
        }
        for (i, e) in self.effects.iter().enumerate() {
            if self.effects[..i].contains(e) {
                invalid!("effects: `{}` is listed twice", e.name());
            }
        }
        for (field, v) in [
            ("lights.red", self.lights.red),
            ("lights.green", self.lights.green),
            ("lights.blue", self.lights.blue),
        ] {
            let norm = v.iter().map(|c| c * c).sum::<f64>().sqrt();
            if !v.iter().all(|c| c.is_finite()) || (norm - 1.0).abs() > 1e-3 || v[2] <= 0.0 {
                invalid!(
                    "{field} must be a unit vector pointing toward the camera (z > 0), got {v:?}"
                );
            }
        }
        self.validate_params()?;
        self.validate_object()
    }

    /// The effects' parameters: blurs, noise, motion errors and illumination in range.
    fn validate_params(&self) -> Result<(), Error> {
        let (p, s) = (&self.params, &self.sensor);
        non_negative("params.gel_sigma_per_thickness", p.gel_sigma_per_thickness)?;
        non_negative("params.defocus_sigma_px", p.defocus_sigma_px)?;
        let gel_sigma_px = p.gel_sigma_per_thickness * s.gel_thickness_mm / s.mm_per_px;
        for (field, sigma) in [
            ("params.gel_sigma_per_thickness", gel_sigma_px),
            ("params.defocus_sigma_px", p.defocus_sigma_px),
        ] {
            if sigma > 256.0 {
                invalid!("{field}: a blur of σ = {sigma:.0} px is more than 256 px");
            }
        }
        non_negative("params.read_noise", p.read_noise)?;
        non_negative("params.shot_noise", p.shot_noise)?;
        for (field, px) in [
            ("params.jitter_px", p.jitter_px),
            ("params.wander_px", p.wander_px),
        ] {
            non_negative(field, px)?;
            if px > 1000.0 {
                invalid!("{field} must be at most 1000, got {px}");
            }
        }
        if !(0.0..1.0).contains(&p.speed_jitter) {
            invalid!(
                "params.speed_jitter must be in 0..1, got {}",
                p.speed_jitter
            );
        }
        if !(0.0..1.0).contains(&p.vignetting) {
            invalid!("params.vignetting must be in 0..1, got {}", p.vignetting);
        }
        if !(-1.0..1.0).contains(&p.gradient) {
            invalid!("params.gradient must be in -1..1, got {}", p.gradient);
        }
        Ok(())
    }

    /// What a valid scene will not show, said before it is rendered: no object pressed in
    /// at all, or a press deeper than the gel (contact flattens against the roller and the
    /// frames lose their features).
    pub fn warnings(&self) -> Vec<String> {
        let s = &self.sensor;
        let mut out = Vec::new();
        if s.press_depth_mm == 0.0 {
            out.push(
                "sensor.press_depth_mm is 0: nothing presses into the gel, every frame is flat"
                    .into(),
            );
        }
        if s.press_depth_mm > s.gel_thickness_mm {
            out.push(format!(
                "sensor.press_depth_mm ({}) is deeper than the gel (sensor.gel_thickness_mm = {}): the frames show no contact detail",
                s.press_depth_mm, s.gel_thickness_mm
            ));
        }
        out
    }

    fn validate_object(&self) -> Result<(), Error> {
        match &self.object {
            Object::Letters { text, height_mm } => validate_letters(text, *height_mm)?,
            Object::Dots {
                height_mm,
                pitch_mm,
                size_mm,
            }
            | Object::Lines {
                height_mm,
                pitch_mm,
                size_mm,
            }
            | Object::Curves {
                height_mm,
                pitch_mm,
                size_mm,
            } => validate_grid(*height_mm, *pitch_mm, *size_mm, self.sensor.mm_per_px)?,
            Object::Spheres { diameter_mm } => positive("object.diameter_mm", *diameter_mm)?,
            Object::Fabric { yarn_mm, pitch_mm } => {
                positive("object.yarn_mm", *yarn_mm)?;
                at_least_a_pixel("object.pitch_mm", *pitch_mm, self.sensor.mm_per_px)?;
            }
            Object::Screw {
                diameter_mm,
                pitch_mm,
            } => {
                positive("object.diameter_mm", *diameter_mm)?;
                at_least_a_pixel("object.pitch_mm", *pitch_mm, self.sensor.mm_per_px)?;
            }
            Object::Paperclip { wire_mm } => positive("object.wire_mm", *wire_mm)?,
            Object::Textile {
                fabric,
                defects,
                scale,
            } => validate_textile(fabric, *defects, *scale)?,
            Object::Primitives { shapes } => validate_primitives(shapes)?,
        }
        Ok(())
    }
}

/// The letters: a short text the font can draw, raised.
fn validate_letters(text: &str, height_mm: f64) -> Result<(), Error> {
    positive("object.height_mm", height_mm)?;
    if text.trim().is_empty() || text.chars().count() > 64 {
        invalid!("object.text must have 1..=64 characters");
    }
    if let Some(c) = text.chars().find(|c| !rollfuse_io::font::supports(*c)) {
        invalid!("object.text: no glyph for {c:?} (A–Z, 0–9 and space)");
    }
    Ok(())
}

/// A grid of dots, lines or curves: raised, each smaller than the grid's pitch, and the
/// pitch at least a pixel.
fn validate_grid(height_mm: f64, pitch_mm: f64, size_mm: f64, mm_per_px: f64) -> Result<(), Error> {
    positive("object.height_mm", height_mm)?;
    at_least_a_pixel("object.pitch_mm", pitch_mm, mm_per_px)?;
    positive("object.size_mm", size_mm)?;
    if size_mm >= pitch_mm {
        invalid!("object.size_mm ({size_mm}) must be smaller than object.pitch_mm ({pitch_mm})");
    }
    Ok(())
}

/// Primitives: at least one, their region names usable and distinct, each shape sound.
fn validate_primitives(shapes: &[Shape]) -> Result<(), Error> {
    if shapes.is_empty() {
        invalid!("object.shapes must list at least one shape");
    }
    validate_region_names(shapes)?;
    for (i, shape) in shapes.iter().enumerate() {
        validate_shape(i, shape)?;
    }
    Ok(())
}

/// Region names: letters, digits, '_' or '-', none used twice.
fn validate_region_names(shapes: &[Shape]) -> Result<(), Error> {
    let mut names: Vec<&str> = Vec::new();
    for (i, shape) in shapes.iter().enumerate() {
        let (Shape::Sphere {
            region: Some(name), ..
        }
        | Shape::Box {
            region: Some(name), ..
        }) = shape
        else {
            continue;
        };
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            invalid!("object.shapes[{i}].region must be letters, digits, '_' or '-', got {name:?}");
        }
        if names.contains(&name.as_str()) {
            invalid!("object.shapes[{i}].region {name:?} is used twice");
        }
        names.push(name);
    }
    Ok(())
}

/// Shape `i`: finite position, positive size, a sphere's cap no higher than its diameter.
fn validate_shape(i: usize, shape: &Shape) -> Result<(), Error> {
    let at = |f: &str| format!("object.shapes[{i}].{f}");
    match shape {
        Shape::Sphere {
            x_mm,
            y_mm,
            radius_mm,
            height_mm,
            ..
        } => {
            finite(&at("x_mm"), *x_mm)?;
            finite(&at("y_mm"), *y_mm)?;
            positive(&at("radius_mm"), *radius_mm)?;
            if let Some(h) = height_mm {
                positive(&at("height_mm"), *h)?;
                if *h > 2.0 * radius_mm {
                    invalid!("{} ({h}) must not exceed the diameter", at("height_mm"));
                }
            }
        }
        Shape::Box {
            x_mm,
            y_mm,
            width_mm,
            length_mm,
            height_mm,
            ..
        } => {
            finite(&at("x_mm"), *x_mm)?;
            finite(&at("y_mm"), *y_mm)?;
            positive(&at("width_mm"), *width_mm)?;
            positive(&at("length_mm"), *length_mm)?;
            positive(&at("height_mm"), *height_mm)?;
        }
    }
    Ok(())
}

/// The largest magnitude of any number in a scene: far beyond any real roller or belt
/// (a kilometre in mm), yet small enough that no product the renderer forms (squares,
/// areas, sums of thousands of terms) can overflow to infinity.
pub const MAX_SCENE_VALUE: f64 = 1e6;

/// `v` as a message shows it: plain, or in exponent form when too large to read plainly.
fn shown(v: f64) -> String {
    if v.abs() < MAX_SCENE_VALUE * 10.0 {
        v.to_string()
    } else {
        format!("{v:e}")
    }
}

/// Whether `v` is a number a scene may hold.
fn in_range(v: f64) -> bool {
    v.is_finite() && v.abs() <= MAX_SCENE_VALUE
}

fn finite(field: &str, v: f64) -> Result<(), Error> {
    if !in_range(v) {
        invalid!(
            "{field} must be a finite number of at most {MAX_SCENE_VALUE:e}, got {}",
            shown(v)
        );
    }
    Ok(())
}

fn positive(field: &str, v: f64) -> Result<(), Error> {
    if !(in_range(v) && v > 0.0) {
        invalid!(
            "{field} must be a positive number of at most {MAX_SCENE_VALUE:e}, got {}",
            shown(v)
        );
    }
    Ok(())
}

fn at_least_a_pixel(field: &str, v: f64, mm_per_px: f64) -> Result<(), Error> {
    if !(in_range(v) && v >= mm_per_px) {
        invalid!(
            "{field} must be at least one pixel ({mm_per_px} mm) and at most {MAX_SCENE_VALUE:e}, got {}",
            shown(v)
        );
    }
    Ok(())
}

fn non_negative(field: &str, v: f64) -> Result<(), Error> {
    if !(in_range(v) && v >= 0.0) {
        invalid!(
            "{field} must be zero or positive, at most {MAX_SCENE_VALUE:e}, got {}",
            shown(v)
        );
    }
    Ok(())
}
