//! The user's labelled images, from a COCO detection file or a folder of YOLO labels.
//!
//! - **COCO**: `images` (`id`, `file_name`, optional `width`, `height`), `annotations`
//!   (`image_id`, `bbox` as `[x, y, w, h]` in pixels, `category_id`) and `categories`
//!   (`id`, `name`: `hole`, `snag` or `slub`).
//! - **YOLO**: for each PNG image of the images folder, a text file of its stem in the
//!   labels folder with a line `class cx cy w h` per box (the box's centre and size as
//!   fractions of the image), and the class names, one a line in class order, in
//!   `classes.txt` (or `obj.names`, as CVAT exports it). An image without a label file is
//!   defect-free, as in YOLO's own tools.
//!
//! Everything is checked before any training: an unknown category, an annotation of an
//! image the file does not list, a box that is not finite, empty or outside its image, an
//! image that is missing, not gray, smaller than the detector takes or of another size
//! than the file says — each is one error naming the image or the annotation. An image
//! with no annotations is a defect-free example.

use super::check_input;
use super::targets::Labelled;
use anyhow::Context;
use rollfuse_io::image::{PixelLimit, Planes};
use rollfuse_sim::textile::DefectKind;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Largest labels file read, bytes.
pub const MAX_LABELS_BYTES: u64 = 64 << 20;
/// Most images one labels file lists.
pub const MAX_IMAGES: usize = 100_000;
/// Most pixels of all the listed images together (they are held at once, 4 bytes a
/// pixel: 1 GiB).
pub const MAX_TOTAL_PIXELS: usize = 1 << 28;
/// Largest YOLO label file read (one image's boxes), bytes.
pub const MAX_YOLO_FILE_BYTES: u64 = 1 << 20;
/// The files a YOLO labels folder names its classes in, looked for in this order.
pub const YOLO_CLASS_FILES: [&str; 2] = ["classes.txt", "obj.names"];

/// One labelled image.
#[derive(Debug, Clone)]
pub struct LabelledImage {
    /// The gray image.
    pub image: Planes,
    /// Its defects, in pixels.
    pub boxes: Vec<Labelled>,
}

#[derive(Deserialize)]
struct Coco {
    images: Vec<CocoImage>,
    #[serde(default)]
    annotations: Vec<CocoAnnotation>,
    categories: Vec<CocoCategory>,
}

#[derive(Deserialize)]
struct CocoImage {
    id: u64,
    file_name: String,
    width: Option<usize>,
    height: Option<usize>,
}

#[derive(Deserialize)]
struct CocoAnnotation {
    image_id: u64,
    bbox: [f64; 4],
    category_id: u64,
}

#[derive(Deserialize)]
struct CocoCategory {
    id: u64,
    name: String,
}

/// Reads `labels` — a COCO file, or a folder of YOLO labels — and the images it labels,
/// found in the folder `images`, each within `limit`.
pub fn read_labels(
    labels: &Path,
    images: &Path,
    limit: PixelLimit,
) -> crate::Result<Vec<LabelledImage>> {
    if labels.is_dir() {
        read_yolo(labels, images, limit)
    } else {
        read_coco(labels, images, limit)
    }
}

/// Reads the COCO file `labels` and the images it lists, found under `images`, each
/// within `limit`.
pub fn read_coco(
    labels: &Path,
    images: &Path,
    limit: PixelLimit,
) -> crate::Result<Vec<LabelledImage>> {
    let shown = labels.display();
    let size = std::fs::metadata(labels)
        .with_context(|| format!("cannot read labels {shown}"))?
        .len();
    rollfuse_io::require!(
        size <= MAX_LABELS_BYTES,
        "labels {shown} is {size} bytes, more than the {MAX_LABELS_BYTES} read"
    );
    let text =
        std::fs::read_to_string(labels).with_context(|| format!("cannot read labels {shown}"))?;
    let coco: Coco = serde_json::from_str(&text)
        .with_context(|| format!("labels {shown} is not a COCO detection file"))?;
    rollfuse_io::require!(!coco.images.is_empty(), "labels {shown} lists no images");
    rollfuse_io::require!(
        coco.images.len() <= MAX_IMAGES,
        "labels {shown} lists {} images, more than the {MAX_IMAGES} read",
        coco.images.len()
    );
    let kinds = categories(&coco.categories).with_context(|| format!("labels {shown}"))?;
    let mut boxes: HashMap<u64, Vec<Labelled>> = HashMap::new();
    for image in &coco.images {
        rollfuse_io::require!(
            boxes.insert(image.id, Vec::new()).is_none(),
            "labels {shown}: image id {} is listed twice",
            image.id
        );
    }
    for (k, a) in coco.annotations.iter().enumerate() {
        let kind = *kinds.get(&a.category_id).with_context(|| {
            format!(
                "labels {shown}: annotation {k} has category {}, which `categories` does not list",
                a.category_id
            )
        })?;
        let list = boxes.get_mut(&a.image_id).with_context(|| {
            format!(
                "labels {shown}: annotation {k} is of image {}, which `images` does not list",
                a.image_id
            )
        })?;
        let [x, y, w, h] = a.bbox;
        rollfuse_io::require!(
            a.bbox.iter().all(|v| v.is_finite()) && w > 0.0 && h > 0.0,
            "labels {shown}: annotation {k}'s box {:?} is not a box (x, y, width, height)",
            a.bbox
        );
        list.push(Labelled {
            kind,
            box_px: [x, y, x + w, y + h].map(|v| v as f32),
        });
    }
    let mut pixels = 0usize;
    coco.images
        .iter()
        .map(|i| {
            let boxes = boxes.remove(&i.id).unwrap_or_default();
            let loaded = load(i, boxes, images, limit)?;
            count_pixels(&mut pixels, &loaded.image, labels)?;
            Ok(loaded)
        })
        .collect()
}

/// Adds `image`'s pixels to `total`, refusing more than fine-tuning holds at once.
fn count_pixels(total: &mut usize, image: &Planes, labels: &Path) -> crate::Result<()> {
    *total += image.width * image.height;
    rollfuse_io::require!(
        *total <= MAX_TOTAL_PIXELS,
        "labels {}: its images hold more than the {MAX_TOTAL_PIXELS} pixels fine-tuning \
         reads at once; give fewer",
        labels.display()
    );
    Ok(())
}

/// The defect kind of each category id; every name must be one the detector knows.
fn categories(list: &[CocoCategory]) -> crate::Result<HashMap<u64, DefectKind>> {
    let mut kinds = HashMap::new();
    for c in list {
        rollfuse_io::require!(
            kinds.insert(c.id, kind_named(&c.name)?).is_none(),
            "category id {} is listed twice",
            c.id
        );
    }
    Ok(kinds)
}

/// The defect kind a label's class is named for, in any case.
fn kind_named(name: &str) -> crate::Result<DefectKind> {
    Ok(DefectKind::ALL
        .into_iter()
        .find(|k| k.name() == name.trim().to_lowercase())
        .with_context(|| {
            let names: Vec<&str> = DefectKind::ALL.iter().map(|k| k.name()).collect();
            format!(
                "{name:?} is not a defect the detector knows ({})",
                names.join(", ")
            )
        })?)
}

/// Loads one listed image and checks its boxes against it.
fn load(
    i: &CocoImage,
    boxes: Vec<Labelled>,
    dir: &Path,
    limit: PixelLimit,
) -> crate::Result<LabelledImage> {
    let path = dir.join(&i.file_name);
    let shown = path.display();
    let image =
        Planes::load(&path, limit).with_context(|| format!("image {} of the labels", i.id))?;
    check_input(&image).with_context(|| shown.to_string())?;
    let (w, h) = (image.width, image.height);
    if let (Some(lw), Some(lh)) = (i.width, i.height)
        && (lw, lh) != (w, h)
    {
        rollfuse_io::invalid!("{shown} is {w}×{h}, but the labels say {lw}×{lh}");
    }
    let boxes = boxes
        .into_iter()
        .map(|mut b| {
            let [x0, y0, x1, y1] = b.box_px;
            let (wf, hf) = (w as f32, h as f32);
            rollfuse_io::require!(
                x0 < wf && y0 < hf && x1 > 0.0 && y1 > 0.0,
                "{shown}: a {} box {:?} lies outside the {w}×{h} image",
                b.kind.name(),
                b.box_px
            );
            b.box_px = [x0.max(0.0), y0.max(0.0), x1.min(wf), y1.min(hf)];
            Ok(b)
        })
        .collect::<crate::Result<_>>()?;
    Ok(LabelledImage { image, boxes })
}

/// Reads the YOLO labels in the folder `labels` for the PNG images of the folder `images`,
/// each within `limit`.
pub fn read_yolo(
    labels: &Path,
    images: &Path,
    limit: PixelLimit,
) -> crate::Result<Vec<LabelledImage>> {
    let kinds = yolo_classes(labels)?;
    let paths = png_files(images)?;
    let (mut pixels, mut labelled) = (0usize, 0usize);
    let mut out = Vec::with_capacity(paths.len());
    for path in paths {
        let shown = path.display();
        let image = Planes::load(&path, limit)?;
        check_input(&image).with_context(|| shown.to_string())?;
        count_pixels(&mut pixels, &image, labels)?;
        // `frame.v2.png` → `frame.v2.txt`: the stem whole, whatever dots it holds.
        let mut name = path.file_stem().unwrap_or_default().to_os_string();
        name.push(".txt");
        let txt = labels.join(name);
        let boxes = match read_small(&txt)? {
            Some(text) => {
                labelled += 1;
                yolo_boxes(&text, &kinds, image.width, image.height)
                    .with_context(|| format!("labels {}", txt.display()))?
            }
            None => Vec::new(),
        };
        out.push(LabelledImage { image, boxes });
    }
    rollfuse_io::require!(
        labelled > 0,
        "no image of {} has a label file in {} (a YOLO label file is the image's name with \
         .txt)",
        images.display(),
        labels.display()
    );
    Ok(out)
}

/// The defect kind of each YOLO class index, from the folder's class file.
fn yolo_classes(labels: &Path) -> crate::Result<Vec<DefectKind>> {
    let Some(path) = YOLO_CLASS_FILES
        .iter()
        .map(|name| labels.join(name))
        .find(|p| p.is_file())
    else {
        rollfuse_io::invalid!(
            "YOLO labels {} name no classes: put their names (hole, snag, slub), one a line \
             in class order, in {} there",
            labels.display(),
            YOLO_CLASS_FILES.join(" or ")
        );
    };
    let text = read_small(&path)?.unwrap_or_default();
    let kinds: Vec<DefectKind> = text
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(kind_named)
        .collect::<crate::Result<_>>()
        .with_context(|| path.display().to_string())?;
    rollfuse_io::require!(!kinds.is_empty(), "{} names no classes", path.display());
    Ok(kinds)
}

/// The PNG files of `dir`, by name.
fn png_files(dir: &Path) -> crate::Result<Vec<PathBuf>> {
    let entries =
        std::fs::read_dir(dir).with_context(|| format!("cannot read images {}", dir.display()))?;
    let mut paths = Vec::new();
    for entry in entries {
        let path = entry?.path();
        let png = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if png && path.is_file() {
            paths.push(path);
        }
    }
    rollfuse_io::require!(!paths.is_empty(), "{} holds no PNG images", dir.display());
    rollfuse_io::require!(
        paths.len() <= MAX_IMAGES,
        "{} holds {} PNG images, more than the {MAX_IMAGES} read",
        dir.display(),
        paths.len()
    );
    paths.sort();
    Ok(paths)
}

/// A small text file's contents; `None` when it does not exist.
fn read_small(path: &Path) -> crate::Result<Option<String>> {
    let size = match std::fs::metadata(path) {
        Ok(m) => m.len(),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => {
            let e = anyhow::Error::from(e).context(format!("cannot read {}", path.display()));
            return Err(e.into());
        }
    };
    rollfuse_io::require!(
        size <= MAX_YOLO_FILE_BYTES,
        "{} is {size} bytes, more than the {MAX_YOLO_FILE_BYTES} read",
        path.display()
    );
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(Some(text))
}

/// One image's YOLO boxes (`class cx cy w h`, fractions of the `w` × `h` image) in pixels.
fn yolo_boxes(
    text: &str,
    kinds: &[DefectKind],
    w: usize,
    h: usize,
) -> crate::Result<Vec<Labelled>> {
    let mut boxes = Vec::new();
    for (n, line) in text.lines().enumerate().map(|(k, l)| (k + 1, l)) {
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.is_empty() {
            continue;
        }
        rollfuse_io::require!(
            fields.len() == 5,
            "line {n} has {} values, not a box's 5 (class cx cy w h; segmentation outlines \
             are not read)",
            fields.len()
        );
        let class: usize = fields[0]
            .parse()
            .with_context(|| format!("line {n}: class {:?} is not a class number", fields[0]))?;
        let kind = *kinds.get(class).with_context(|| {
            format!(
                "line {n}: class {class}, but the class file names {}",
                kinds.len()
            )
        })?;
        let v: Vec<f64> = fields[1..]
            .iter()
            .map(|f| f.parse::<f64>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("line {n}: {line:?} is not four numbers after the class"))?;
        let (cx, cy, bw, bh) = (v[0], v[1], v[2], v[3]);
        rollfuse_io::require!(
            v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)) && bw > 0.0 && bh > 0.0,
            "line {n}: {line:?} is not a box in fractions of the image (centre and size, \
             each 0 to 1; pixel boxes are COCO's)"
        );
        let (wf, hf) = (w as f64, h as f64);
        let px = [
            ((cx - bw / 2.0) * wf).max(0.0),
            ((cy - bh / 2.0) * hf).max(0.0),
            ((cx + bw / 2.0) * wf).min(wf),
            ((cy + bh / 2.0) * hf).min(hf),
        ];
        boxes.push(Labelled {
            kind,
            box_px: px.map(|x| x as f32),
        });
    }
    Ok(boxes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_gray(path: &Path, w: usize, h: usize) {
        let planes = Planes {
            width: w,
            height: h,
            planes: vec![vec![100.0; w * h]],
        };
        planes.save_png(path).unwrap();
    }

    /// A folder with two 64 × 48 images and `labels.json` holding `json`.
    fn folder(json: &str) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        write_gray(&dir.path().join("a.png"), 64, 48);
        write_gray(&dir.path().join("b.png"), 64, 48);
        std::fs::write(dir.path().join("labels.json"), json).unwrap();
        dir
    }

    const CATEGORIES: &str =
        r#""categories": [{"id": 1, "name": "hole"}, {"id": 7, "name": "Slub"}]"#;

    fn read(json: &str) -> crate::Result<Vec<LabelledImage>> {
        let dir = folder(json);
        read_coco(
            &dir.path().join("labels.json"),
            dir.path(),
            PixelLimit::default(),
        )
    }

    #[test]
    fn boxes_are_read_in_pixels_by_kind_and_clipped_to_their_image() {
        let json = format!(
            r#"{{"images": [{{"id": 3, "file_name": "a.png", "width": 64, "height": 48}},
                           {{"id": 4, "file_name": "b.png"}}],
               "annotations": [{{"id": 1, "image_id": 3, "bbox": [10, 5, 20, 8], "category_id": 7}},
                               {{"id": 2, "image_id": 3, "bbox": [50, 40, 30, 30], "category_id": 1}}],
               {CATEGORIES}}}"#
        );
        let images = read(&json).unwrap();
        assert_eq!(images.len(), 2);
        let a = &images[0].boxes;
        assert_eq!(a[0].kind, DefectKind::Slub);
        assert_eq!(a[0].box_px, [10.0, 5.0, 30.0, 13.0]);
        assert_eq!(a[1].kind, DefectKind::Hole);
        assert_eq!(a[1].box_px, [50.0, 40.0, 64.0, 48.0]);
        // An image without annotations is defect-free.
        assert!(images[1].boxes.is_empty());
    }

    #[test]
    fn bad_labels_are_refused_naming_what_is_wrong() {
        let image = r#""images": [{"id": 3, "file_name": "a.png"}]"#;
        let cases = [
            (
                format!(r#"{{{image}, "categories": [{{"id": 1, "name": "stain"}}]}}"#),
                "\"stain\" is not a defect",
            ),
            (
                format!(
                    r#"{{{image}, "annotations": [{{"image_id": 9, "bbox": [1, 1, 4, 4], "category_id": 1}}], {CATEGORIES}}}"#
                ),
                "of image 9, which `images` does not list",
            ),
            (
                format!(
                    r#"{{{image}, "annotations": [{{"image_id": 3, "bbox": [1, 1, 4, 4], "category_id": 2}}], {CATEGORIES}}}"#
                ),
                "category 2",
            ),
            (
                format!(
                    r#"{{{image}, "annotations": [{{"image_id": 3, "bbox": [1, 1, 0, 4], "category_id": 1}}], {CATEGORIES}}}"#
                ),
                "is not a box",
            ),
            (
                format!(
                    r#"{{{image}, "annotations": [{{"image_id": 3, "bbox": [70, 1, 4, 4], "category_id": 1}}], {CATEGORIES}}}"#
                ),
                "lies outside the 64×48 image",
            ),
            (
                format!(
                    r#"{{"images": [{{"id": 3, "file_name": "a.png", "width": 32, "height": 48}}], {CATEGORIES}}}"#
                ),
                "but the labels say 32×48",
            ),
            (
                format!(r#"{{"images": [{{"id": 3, "file_name": "gone.png"}}], {CATEGORIES}}}"#),
                "image 3 of the labels",
            ),
            (
                format!(r#"{{{image}, {image}, {CATEGORIES}}}"#),
                "not a COCO detection file",
            ),
            (
                format!(r#"{{"images": [], {CATEGORIES}}}"#),
                "lists no images",
            ),
            (
                format!(
                    r#"{{"images": [{{"id": 3, "file_name": "a.png"}}, {{"id": 3, "file_name": "b.png"}}], {CATEGORIES}}}"#
                ),
                "image id 3 is listed twice",
            ),
        ];
        for (json, says) in cases {
            let e = format!("{:#}", read(&json).unwrap_err());
            assert!(e.contains(says), "{json}\n→ {e}");
        }
    }

    /// A folder of YOLO labels for `folder`'s two images, `a.txt` holding `a`.
    fn yolo(classes: &str, a: &str) -> crate::Result<Vec<LabelledImage>> {
        let dir = folder("{}");
        let labels = dir.path().join("labels");
        std::fs::create_dir(&labels).unwrap();
        std::fs::write(labels.join("classes.txt"), classes).unwrap();
        std::fs::write(labels.join("a.txt"), a).unwrap();
        read_labels(&labels, dir.path(), PixelLimit::default())
    }

    #[test]
    fn yolo_boxes_are_read_from_fractions_by_class_and_clipped() {
        let images = yolo(
            "snag\nHole\n",
            "1 0.25 0.5 0.125 0.25\n\n0 0.95 0.1 0.2 0.5\n",
        )
        .unwrap();
        assert_eq!(images.len(), 2);
        let a = &images[0].boxes;
        assert_eq!(a[0].kind, DefectKind::Hole);
        assert_eq!(a[0].box_px, [12.0, 18.0, 20.0, 30.0]);
        assert_eq!(a[1].kind, DefectKind::Snag);
        assert_eq!(a[1].box_px, [54.4, 0.0, 64.0, 16.8]);
        // b.png has no label file: defect-free.
        assert!(images[1].boxes.is_empty());
    }

    #[test]
    fn a_yolo_label_file_is_the_images_whole_stem_with_txt() {
        let dir = folder("{}");
        write_gray(&dir.path().join("roll.v2.png"), 64, 48);
        let labels = dir.path().join("labels");
        std::fs::create_dir(&labels).unwrap();
        std::fs::write(labels.join("classes.txt"), "hole\n").unwrap();
        std::fs::write(labels.join("roll.v2.txt"), "0 0.5 0.5 0.25 0.25\n").unwrap();
        // Not this image's labels: read, it would be refused.
        std::fs::write(labels.join("roll.txt"), "not a box\n").unwrap();
        let images = read_labels(&labels, dir.path(), PixelLimit::default()).unwrap();
        let boxes: Vec<usize> = images.iter().map(|i| i.boxes.len()).collect();
        assert_eq!(boxes, [0, 0, 1], "a.png, b.png, roll.v2.png");
    }

    #[test]
    fn bad_yolo_labels_are_refused_naming_what_is_wrong() {
        let cases = [
            ("stain\n", "0 0.5 0.5 0.1 0.1", "\"stain\" is not a defect"),
            (
                "hole\n",
                "1 0.5 0.5 0.1 0.1",
                "line 1: class 1, but the class file names 1",
            ),
            ("hole\n", "0 32 24 10 10", "fractions of the image"),
            ("hole\n", "0 0.5 0.5 0 0.1", "fractions of the image"),
            ("hole\n", "0 0.1 0.1 0.2 0.1 0.3 0.3", "7 values"),
            ("hole\n", "x 0.5 0.5 0.1 0.1", "not a class number"),
            ("hole\n", "0 0.5 NaN 0.1 0.1", "fractions of the image"),
            ("\n", "0 0.5 0.5 0.1 0.1", "names no classes"),
        ];
        for (classes, a, says) in cases {
            let e = format!("{:#}", yolo(classes, a).unwrap_err());
            assert!(e.contains(says), "{classes:?} / {a:?}\n→ {e}");
        }
        // No class file, and no label file for any image.
        let dir = folder("{}");
        let e = format!(
            "{:#}",
            read_labels(dir.path(), dir.path(), PixelLimit::default()).unwrap_err()
        );
        assert!(e.contains("name no classes"), "{e}");
        std::fs::write(dir.path().join("obj.names"), "hole\n").unwrap();
        let e = format!(
            "{:#}",
            read_labels(dir.path(), dir.path(), PixelLimit::default()).unwrap_err()
        );
        assert!(e.contains("no image of"), "{e}");
    }
}
