//! Whether an image looks like the cloth a model was trained on.
//!
//! A classifier's softmax says which known fabric an image is most like, never that it is
//! like none of them (the shipped classifier gives frames of the letters scene, no fabric
//! at all, `canvas` at 0.94–0.98). Each
//! place of the image — a texture cell ([`super::cells::TEXTURE`]: 32 × 32 pixels
//! every 8, the log energy of 4 Haar octaves in 3 orientations and the mean, after the
//! image's median and spread are taken out) — is compared instead with the training
//! cloth, modelled as a Gaussian per fabric with one covariance shared by all (the
//! class-conditional Gaussians of Lee et al., *A simple unified framework for detecting
//! out-of-distribution samples*, NeurIPS 2018, taken place by place). A place's
//! **distance** is its squared Mahalanobis distance to the nearest fabric's mean, per
//! feature; an image's is the [`PLACE_QUANTILE`] of its places' (cloth is cloth almost
//! everywhere, a defect is a few places); its **unfamiliarity** is that over the
//! [`CALIBRATION_QUANTILE`] of the distances of held-out images of known cloth. Above 1
//! the image is reported as an unknown fabric.
//!
//! Why texture statistics and not the network's own features: measured on the letters
//! scene and the independently rendered roll of shapes, the network's deepest features
//! (pooled over the image, or place by place) put both as near the training cloth as the
//! cloth itself — the network never had to tell cloth from anything else — while these
//! cells put them 3 to 16 times further than cloth (docs/detect.md).
//!
//! The statistics travel in the model file's metadata (`familiarity`, JSON), so a model
//! without them (trained before they existed) still loads and simply cannot say.

use anyhow::Context;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// The share of held-out images of known cloth the calibrated limit keeps familiar.
pub const CALIBRATION_QUANTILE: f64 = 0.995;
/// The quantile of its places' distances an image is judged by.
pub const PLACE_QUANTILE: f64 = 0.95;
/// How far the shared covariance is shrunk toward its diagonal (the features of many
/// thousand places are well determined; this only guards their smallest directions).
const SHRINK: f64 = 0.05;
/// The fewest images a fit and a calibration take.
pub const MIN_IMAGES: usize = 20;
/// The places each kind of image contributes to the fit, spread evenly over its images
/// and their places: frames and fused tiles weigh alike however many there are of each,
/// and a few thousand images stay within memory.
const PLACES_PER_KIND: usize = 100_000;

/// One kind of image (camera frames, fused tiles): the images to fit and those held out.
#[derive(Debug, Clone, Default)]
pub struct Kind {
    /// Each image's places and its fabric.
    pub fit: Vec<(Places, usize)>,
    /// Images of known cloth the fit does not see.
    pub held_out: Vec<Places>,
}

/// The features of one image's places, place after place.
#[derive(Debug, Clone, PartialEq)]
pub struct Places {
    /// Features a place.
    pub dim: usize,
    /// `dim` values for each place.
    pub data: Vec<f32>,
}

impl Places {
    /// The places of an image: its texture cells.
    pub fn of(image: &rollfuse_io::image::Planes) -> crate::Result<Self> {
        let cells = super::cells::cells(image, super::cells::TEXTURE)?;
        Ok(Self {
            dim: cells.dim,
            data: cells.data,
        })
    }

    /// Each place's vector.
    fn each(&self) -> impl Iterator<Item = &[f32]> {
        self.data.chunks_exact(self.dim.max(1))
    }
}

/// The statistics of the training cloth's features.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Familiarity {
    /// Features a place.
    dim: usize,
    /// `L⁻¹` of the shared covariance `L Lᵀ`, row-major: distances are Euclidean after it.
    whitening: Vec<f32>,
    /// Each fabric's mean, whitened, in the model's label order (empty for a fabric the
    /// fit never saw). f32: the features' own precision, and a JSON number round-trips it.
    centres: Vec<Vec<f32>>,
    /// The image distance at [`CALIBRATION_QUANTILE`] of the held-out images.
    limit: f64,
    /// How many images the means and covariance came from, and the limit.
    fitted_on: usize,
    calibrated_on: usize,
}

/// One image's place among the known cloth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verdict {
    /// Distance over the calibrated limit: above 1, unlike the training cloth.
    pub unfamiliarity: f64,
}

impl Verdict {
    /// Whether the image is unlike the training cloth: an unknown fabric.
    pub fn unfamiliar(&self) -> bool {
        self.unfamiliarity > 1.0
    }
}

impl Familiarity {
    /// Fits the means and shared covariance on the kinds' `fit` images, each kind weighing
    /// alike, then the limit on their `held_out` images: the largest of the kinds'
    /// [`CALIBRATION_QUANTILE`]s, so that no kind is called unknown more often than that.
    pub fn fit(kinds: &[Kind], classes: usize) -> crate::Result<Self> {
        let fitted_on: usize = kinds.iter().map(|k| k.fit.len()).sum();
        let calibrated_on: usize = kinds.iter().map(|k| k.held_out.len()).sum();
        rollfuse_io::require!(
            fitted_on >= MIN_IMAGES && calibrated_on >= MIN_IMAGES,
            "familiarity needs at least {MIN_IMAGES} images to fit and {MIN_IMAGES} to calibrate \
             (got {fitted_on} and {calibrated_on})"
        );
        let dim = kinds
            .iter()
            .find_map(|k| k.fit.first())
            .map_or(0, |(p, _)| p.dim);
        rollfuse_io::require!(
            dim > 0
                && kinds.iter().all(|k| {
                    k.fit.iter().all(|(p, c)| p.dim == dim && *c < classes)
                        && k.held_out.iter().all(|p| p.dim == dim)
                }),
            "familiarity's features differ in length or name a fabric out of range"
        );
        let fit = sampled(kinds, dim);
        let mut sums = vec![vec![0f64; dim]; classes];
        let mut counts = vec![0usize; classes];
        for (places, c) in &fit {
            for v in places {
                counts[*c] += 1;
                sums[*c].iter_mut().zip(v).for_each(|(s, x)| *s += x);
            }
        }
        let means: Vec<Vec<f64>> = sums
            .into_iter()
            .zip(&counts)
            .map(|(s, &n)| s.into_iter().map(|v| v / n.max(1) as f64).collect())
            .collect();
        let mut cov = DMatrix::<f64>::zeros(dim, dim);
        let mut total = 0usize;
        for (places, c) in &fit {
            for v in places {
                let d = DVector::from_iterator(dim, v.iter().zip(&means[*c]).map(|(x, m)| x - m));
                cov.syger(1.0, &d, &d, 1.0);
                total += 1;
            }
        }
        rollfuse_io::require!(
            total > dim,
            "familiarity needs more places than features ({total} ≤ {dim})"
        );
        cov.fill_upper_triangle_with_lower_triangle();
        cov /= total as f64;
        let diagonal = DMatrix::from_diagonal(&cov.diagonal());
        let shrunk = cov * (1.0 - SHRINK) + diagonal * SHRINK;
        let floor = shrunk.diagonal().max() * 1e-9 + f64::MIN_POSITIVE;
        let shrunk = shrunk + DMatrix::identity(dim, dim) * floor;
        let whitening = shrunk
            .cholesky()
            .context("the training features' covariance is singular")?
            .l()
            .try_inverse()
            .context("the training features' covariance is singular")?;
        let centres = means
            .iter()
            .zip(&counts)
            .map(|(m, &n)| {
                if n == 0 {
                    return Vec::new();
                }
                let m = DMatrix::from_column_slice(dim, 1, m);
                (&whitening * m).iter().map(|&v| v as f32).collect()
            })
            .collect();
        let mut model = Self {
            dim,
            whitening: whitening
                .transpose()
                .as_slice()
                .iter()
                .map(|&v| v as f32)
                .collect(),
            centres,
            limit: 1.0,
            fitted_on,
            calibrated_on,
        };
        let mut limit = f64::MIN_POSITIVE;
        for kind in kinds.iter().filter(|k| !k.held_out.is_empty()) {
            let mut distances: Vec<f64> = kind
                .held_out
                .iter()
                .map(|p| model.distance(p))
                .collect::<crate::Result<_>>()?;
            distances.sort_by(f64::total_cmp);
            limit = limit.max(quantile(&distances, CALIBRATION_QUANTILE));
        }
        model.limit = limit;
        Ok(model)
    }

    /// One place's squared distance per feature to the nearest fabric.
    fn place_distance(&self, v: &[f32], white: &mut [f64]) -> f64 {
        for (w, row) in white.iter_mut().zip(self.whitening.chunks_exact(self.dim)) {
            *w = row
                .iter()
                .zip(v)
                .map(|(&a, &x)| f64::from(a) * f64::from(x))
                .sum();
        }
        self.centres
            .iter()
            .filter(|c| !c.is_empty())
            .map(|c| {
                c.iter()
                    .zip(white.iter())
                    .map(|(&m, &x)| (x - f64::from(m)).powi(2))
                    .sum::<f64>()
            })
            .fold(f64::INFINITY, f64::min)
            / self.dim as f64
    }

    /// An image's distance: the [`PLACE_QUANTILE`] of its places'.
    fn distance(&self, places: &Places) -> crate::Result<f64> {
        rollfuse_io::require!(
            places.dim == self.dim,
            "the network gives {} features a place, the familiarity statistics describe {}",
            places.dim,
            self.dim
        );
        rollfuse_io::require!(!places.data.is_empty(), "the image has no places to judge");
        let mut white = vec![0f64; self.dim];
        let mut d: Vec<f64> = places
            .each()
            .map(|v| self.place_distance(v, &mut white))
            .collect();
        d.sort_by(f64::total_cmp);
        let q = quantile(&d, PLACE_QUANTILE);
        rollfuse_io::require!(q.is_finite(), "the image's features are not finite numbers");
        Ok(q)
    }

    /// Where the places of one image lie among the known cloth.
    pub fn judge(&self, places: &Places) -> crate::Result<Verdict> {
        Ok(Verdict {
            unfamiliarity: self.distance(places)? / self.limit,
        })
    }

    /// The statistics as the model file's metadata stores them.
    pub fn to_metadata(&self) -> crate::Result<String> {
        Ok(serde_json::to_string(self).context("cannot encode the familiarity statistics")?)
    }

    /// Reads and checks the metadata for a network of `dim` features and `classes` fabrics.
    pub fn from_metadata(text: &str, dim: usize, classes: usize) -> crate::Result<Self> {
        let model: Self =
            serde_json::from_str(text).context("its familiarity statistics are unreadable")?;
        rollfuse_io::require!(
            model.dim == dim
                && model.centres.len() == classes
                && model.centres.iter().all(|m| m.is_empty() || m.len() == dim)
                && model.centres.iter().any(|m| !m.is_empty())
                && model.whitening.len() == dim * dim,
            "its familiarity statistics do not fit a network of {dim} features and {classes} fabrics"
        );
        rollfuse_io::require!(
            model.limit.is_finite()
                && model.limit > 0.0
                && model.whitening.iter().all(|v| v.is_finite())
                && model.centres.iter().flatten().all(|v| v.is_finite()),
            "its familiarity statistics hold numbers that are not finite"
        );
        Ok(model)
    }
}

/// The places the fit takes from each image of `kinds` (features `dim` long), as f64,
/// with its fabric: [`PLACES_PER_KIND`] spread evenly over each kind.
fn sampled(kinds: &[Kind], dim: usize) -> Vec<(Vec<Vec<f64>>, usize)> {
    let mut fit = Vec::new();
    for kind in kinds.iter().filter(|k| !k.fit.is_empty()) {
        let each = PLACES_PER_KIND.div_ceil(kind.fit.len());
        for (p, c) in &kind.fit {
            let n = p.data.len() / dim;
            let places = p
                .each()
                .step_by(n.div_ceil(each).max(1))
                .map(|v| v.iter().map(|&x| f64::from(x)).collect())
                .collect();
            fit.push((places, *c));
        }
    }
    fit
}

/// The `q` quantile of sorted, non-empty `v` (the nearest rank).
fn quantile(v: &[f64], q: f64) -> f64 {
    v[((v.len() - 1) as f64 * q).round() as usize]
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    /// An image of class `c`: `n` places in a Gaussian-ish blob around `5c` on the first
    /// axis.
    fn image(c: usize, n: usize, dim: usize, rng: &mut Pcg64Mcg) -> Places {
        let data = (0..n * dim)
            .map(|i| {
                let centre = if i % dim == 0 { 5.0 * c as f32 } else { 0.0 };
                centre + rng.random_range(-1.0f32..1.0)
            })
            .collect();
        Places { dim, data }
    }

    fn images(classes: usize, each: usize, rng: &mut Pcg64Mcg) -> Vec<(Places, usize)> {
        (0..classes)
            .flat_map(|c| (0..each).map(move |_| c))
            .map(|c| (image(c, 12, 6, rng), c))
            .collect()
    }

    #[test]
    fn images_like_the_training_cloth_are_familiar_and_others_are_not() {
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        let kind = Kind {
            fit: images(3, 30, &mut rng),
            held_out: images(3, 40, &mut rng).into_iter().map(|p| p.0).collect(),
        };
        let model = Familiarity::fit(std::slice::from_ref(&kind), 3).unwrap();
        let held = &kind.held_out;
        let familiar = held
            .iter()
            .filter(|p| model.judge(p).unwrap().unfamiliarity <= 1.0)
            .count();
        assert!(familiar >= 118, "{familiar} of 120");
        // Most places between the blobs, or far off on another axis: not cloth.
        for far in [
            [2.5f32, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 6.0, 0.0, 0.0, 0.0],
        ] {
            let mut p = image(1, 12, 6, &mut rng);
            for v in p.data.chunks_exact_mut(6).take(10) {
                v.copy_from_slice(&far);
            }
            let v = model.judge(&p).unwrap();
            assert!(v.unfamiliarity > 1.0, "{far:?}: {v:?}");
        }
        // One odd place (a defect) in familiar cloth does not make it unknown.
        let mut p = image(2, 12, 6, &mut rng);
        p.data[..6].copy_from_slice(&[0.0, 0.0, 9.0, 0.0, 0.0, 0.0]);
        assert!(model.judge(&p).unwrap().unfamiliarity <= 1.5);
    }

    #[test]
    fn the_metadata_round_trips_and_is_checked() {
        let mut rng = Pcg64Mcg::seed_from_u64(8);
        let fit = images(2, 20, &mut rng);
        let held_out = fit.iter().map(|(p, _)| p.clone()).collect();
        let model = Familiarity::fit(&[Kind { fit, held_out }], 2).unwrap();
        let text = model.to_metadata().unwrap();
        assert_eq!(Familiarity::from_metadata(&text, 6, 2).unwrap(), model);
        assert!(Familiarity::from_metadata(&text, 5, 2).is_err());
        assert!(Familiarity::from_metadata(&text, 6, 3).is_err());
        assert!(Familiarity::from_metadata("{", 6, 2).is_err());
        let broken = text.replacen("\"limit\":", "\"limit\":-", 1);
        assert!(Familiarity::from_metadata(&broken, 6, 2).is_err());
        let short = Places {
            dim: 3,
            data: vec![0.0; 9],
        };
        assert!(model.judge(&short).is_err());
    }

    #[test]
    fn too_few_images_are_refused() {
        let mut rng = Pcg64Mcg::seed_from_u64(9);
        let fit = images(1, 10, &mut rng);
        let held_out = fit.iter().map(|(p, _)| p.clone()).collect();
        let e = Familiarity::fit(&[Kind { fit, held_out }], 1).unwrap_err();
        assert!(e.to_string().contains("at least"), "{e}");
    }
}
