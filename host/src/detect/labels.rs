//! The user's labelled images, from a COCO detection file: `images` (`id`, `file_name`,
//! optional `width`, `height`), `annotations` (`image_id`, `bbox` as `[x, y, w, h]` in
//! pixels, `category_id`) and `categories` (`id`, `name`: `hole`, `snag` or `slub`).
//!
//! Everything is checked before any training: an unknown category, an annotation of an
//! image the file does not list, a box that is not finite, empty or outside its image, an
//! image that is missing, not gray, smaller than the detector takes or of another size
//! than the file says — each is one error naming the image or the annotation. An image
//! with no annotations is a defect-free example.

use super::check_input;
use super::targets::Labelled;
use crate::image::Planes;
use crate::sim::textile::DefectKind;
use anyhow::{Context, bail, ensure};
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

/// Largest labels file read, bytes.
pub const MAX_LABELS_BYTES: u64 = 64 << 20;
/// Most images one labels file lists.
pub const MAX_IMAGES: usize = 100_000;
/// Most pixels of all the listed images together (they are held at once, 4 bytes a
/// pixel: 1 GiB).
pub const MAX_TOTAL_PIXELS: usize = 1 << 28;

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

/// Reads the COCO file `labels` and the images it lists, found under `images`.
pub fn read_coco(labels: &Path, images: &Path) -> anyhow::Result<Vec<LabelledImage>> {
    let shown = labels.display();
    let size = std::fs::metadata(labels)
        .with_context(|| format!("cannot read labels {shown}"))?
        .len();
    ensure!(
        size <= MAX_LABELS_BYTES,
        "labels {shown} is {size} bytes, more than the {MAX_LABELS_BYTES} read"
    );
    let text =
        std::fs::read_to_string(labels).with_context(|| format!("cannot read labels {shown}"))?;
    let coco: Coco = serde_json::from_str(&text)
        .with_context(|| format!("labels {shown} is not a COCO detection file"))?;
    ensure!(!coco.images.is_empty(), "labels {shown} lists no images");
    ensure!(
        coco.images.len() <= MAX_IMAGES,
        "labels {shown} lists {} images, more than the {MAX_IMAGES} read",
        coco.images.len()
    );
    let kinds = categories(&coco.categories).with_context(|| format!("labels {shown}"))?;
    let mut boxes: HashMap<u64, Vec<Labelled>> = HashMap::new();
    for image in &coco.images {
        ensure!(
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
        ensure!(
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
            let loaded = load(i, boxes, images)?;
            pixels += loaded.image.width * loaded.image.height;
            ensure!(
                pixels <= MAX_TOTAL_PIXELS,
                "labels {shown}: its images hold more than the {MAX_TOTAL_PIXELS} pixels \
                 fine-tuning reads at once; give fewer"
            );
            Ok(loaded)
        })
        .collect()
}

/// The defect kind of each category id; every name must be one the detector knows.
fn categories(list: &[CocoCategory]) -> anyhow::Result<HashMap<u64, DefectKind>> {
    let mut kinds = HashMap::new();
    for c in list {
        let kind = DefectKind::ALL
            .into_iter()
            .find(|k| k.name() == c.name.trim().to_lowercase())
            .with_context(|| {
                let names: Vec<&str> = DefectKind::ALL.iter().map(|k| k.name()).collect();
                format!(
                    "category {:?} is not a defect the detector knows ({})",
                    c.name,
                    names.join(", ")
                )
            })?;
        ensure!(
            kinds.insert(c.id, kind).is_none(),
            "category id {} is listed twice",
            c.id
        );
    }
    Ok(kinds)
}

/// Loads one listed image and checks its boxes against it.
fn load(i: &CocoImage, boxes: Vec<Labelled>, dir: &Path) -> anyhow::Result<LabelledImage> {
    let path = dir.join(&i.file_name);
    let shown = path.display();
    let image = Planes::load(&path).with_context(|| format!("image {} of the labels", i.id))?;
    check_input(&image).with_context(|| shown.to_string())?;
    let (w, h) = (image.width, image.height);
    if let (Some(lw), Some(lh)) = (i.width, i.height)
        && (lw, lh) != (w, h)
    {
        bail!("{shown} is {w}×{h}, but the labels say {lw}×{lh}");
    }
    let boxes = boxes
        .into_iter()
        .map(|mut b| {
            let [x0, y0, x1, y1] = b.box_px;
            let (wf, hf) = (w as f32, h as f32);
            ensure!(
                x0 < wf && y0 < hf && x1 > 0.0 && y1 > 0.0,
                "{shown}: a {} box {:?} lies outside the {w}×{h} image",
                b.kind.name(),
                b.box_px
            );
            b.box_px = [x0.max(0.0), y0.max(0.0), x1.min(wf), y1.min(hf)];
            Ok(b)
        })
        .collect::<anyhow::Result<_>>()?;
    Ok(LabelledImage { image, boxes })
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

    fn read(json: &str) -> anyhow::Result<Vec<LabelledImage>> {
        let dir = folder(json);
        read_coco(&dir.path().join("labels.json"), dir.path())
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
}
