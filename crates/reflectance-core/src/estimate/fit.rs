//! Fitting an estimator and measuring it: leave-one-illumination-out predictions, their
//! errors, the conformal half-widths they give, and the report.

use super::*;

/// Leave-one-illumination-out accuracy of an estimator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct EstimateReport {
    /// Over every row evaluated, the augmented views (captures, rotations, …) among them.
    #[serde(flatten)]
    pub errors: Errors,
    /// Illuminations evaluated (each held out in turn under cross-validation; 0 in model
    /// files written before it was recorded).
    #[serde(default)]
    pub illuminations: usize,
    /// How many rows are augmented views.
    pub augmented: usize,
    /// The intervals' half-widths, from every row's error.
    pub half_widths: HalfWidths,
}

/// The measures over some of the rows (all, the originals, one illumination, …).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Errors {
    /// Rows evaluated.
    pub n: usize,
    /// Mean absolute error of the total reflectance ρd + ρs.
    pub mae_total: f64,
    /// Mean absolute error of ρd.
    pub mae_rho_d: f64,
    /// Mean absolute error of ρs.
    pub mae_rho_s: f64,
    /// Mirror (α = 0) or not, right.
    pub mirror_accuracy: f64,
    /// |log10 α error| over the true non-mirrors the estimate also calls non-mirrors (none
    /// when there are none).
    pub mae_log10_alpha: Option<f64>,
    /// Coverage of the 90 % intervals (in cross-validation each illumination's with
    /// half-widths from the others' errors only).
    pub coverage_rho_d: f64,
    /// Coverage of the ρs intervals.
    pub coverage_rho_s: f64,
    /// Coverage of the α intervals.
    pub coverage_alpha: f64,
}

/// One image's estimate made without its illumination, with intervals sized by the other
/// illuminations' errors (the ones its coverage counts).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldOut {
    /// The image's path, as the table gives it.
    pub path: String,
    /// As written in the table (an augmented view keeps its `@suffix`).
    pub illumination: String,
    /// Its true parameters.
    pub truth: Ward,
    /// The estimate, with its intervals.
    pub estimate: WardEstimate,
}

/// One illumination's errors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IlluminationErrors {
    /// The illumination, as written in the table.
    pub illumination: String,
    /// The measures over its rows.
    #[serde(flatten)]
    pub errors: Errors,
}

/// Everything behind an [`EstimateReport`]: the originals and the augmented views apart,
/// every illumination, every row.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimateDetails {
    /// The measures over the original rows, when there are any.
    pub originals: Option<Errors>,
    /// The measures over the augmented views, when there are any.
    pub augmented: Option<Errors>,
    /// Each illumination's measures.
    pub illuminations: Vec<IlluminationErrors>,
    /// Every row's held-out estimate, in table order.
    pub rows: Vec<HeldOut>,
}

/// A fitted estimator with its leave-one-illumination-out report and details.
pub struct Fit {
    /// The estimator fitted on every row.
    pub regressor: WardRegressor,
    /// Its leave-one-illumination-out report.
    pub report: EstimateReport,
    /// The report's details.
    pub details: EstimateDetails,
}

/// Per row: |errors| of ρd, ρs, t and log10 α, whether the mirror call is right, whether
/// the sphere is glossy (not a mirror), and, once known, which intervals cover it.
struct RowErrors {
    rho_d: f64,
    rho_s: f64,
    total: f64,
    log_alpha: f64,
    mirror_right: bool,
    glossy: bool,
    covered: [bool; 3],
}

fn row_errors(prediction: &[f64], truth: &Ward) -> RowErrors {
    let (Ward { rho_d, rho_s, .. }, log_alpha) = parameters(prediction);
    let predicted_mirror = prediction[2] > 0.0;
    let true_mirror = truth.alpha == 0.0;
    // A mirror's α interval is [0, high]: its error is how far the estimate's log α reaches
    // above the mirror point, and a glossy α's, against its true log α.
    let log_error = match (true_mirror, predicted_mirror) {
        (true, _) => (log_alpha - MIRROR_LOG_ALPHA).max(0.0),
        (false, _) => (log_alpha - truth.alpha.log10()).abs(),
    };
    RowErrors {
        rho_d: (rho_d - truth.rho_d).abs(),
        rho_s: (rho_s - truth.rho_s).abs(),
        total: (rho_d + rho_s - truth.rho_d - truth.rho_s).abs(),
        log_alpha: log_error,
        mirror_right: predicted_mirror == true_mirror,
        glossy: !true_mirror,
        covered: [false; 3],
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// The Ward parameters of `ds`'s classes, from `materials` by name (each class's reference
/// entry, [`crate::material::reference`]).
fn wards_of(ds: &Dataset, materials: &[Material]) -> Result<Vec<Ward>, LearnError> {
    ds.classes
        .iter()
        .map(|c| {
            let material = crate::material::reference(materials, c).ok_or_else(|| {
                LearnError::InvalidParameter(format!("class {c:?} has no Ward parameters"))
            })?;
            Ok(material.ward)
        })
        .collect()
}

/// Fit an estimator on `ds` (from the table named `dataset`), whose classes are materials of
/// `materials` (by name), reading the features of `features`; also its
/// leave-one-illumination-out report and details.
pub fn fit(
    ds: &Dataset,
    dataset: &str,
    materials: &[Material],
    features: &FeatureSet,
    spec: &RegressionSpec,
) -> Result<Fit, LearnError> {
    fit_observed(ds, dataset, materials, features, spec, &Silent)
}

/// [`fit`], reporting the boosted fits' progress to `observer` (which may cancel them).
pub fn fit_observed(
    ds: &Dataset,
    dataset: &str,
    materials: &[Material],
    features: &FeatureSet,
    spec: &RegressionSpec,
    observer: &dyn Observer,
) -> Result<Fit, LearnError> {
    let ward_of_class = wards_of(ds, materials)?;
    let input_indices = features.resolve(&ds.names)?.ok_or_else(|| {
        LearnError::InvalidParameter("estimation needs a fixed feature set".into())
    })?;
    let x = ds.x.select(Axis(1), &input_indices);
    let scaler = Scaler::fit(x.view());
    let z = scaler.transform(x.view());
    let y = Array2::from_shape_fn((ds.n_rows(), 4), |(i, o)| {
        targets(&ward_of_class[ds.labels[i]])[o]
    });
    let total_anchor = input_indices
        .iter()
        .position(|&i| ds.names[i] == TOTAL_ANCHOR);
    let mut fitted_y = y.clone();
    if let Some(k) = total_anchor {
        for (i, mut row) in fitted_y.rows_mut().into_iter().enumerate() {
            row[0] = row[0].max(TOTAL_FLOOR).log10() - x[[i, k]];
        }
    }
    let groups = Some(&ds.groups[..]);
    let (regression, held_out) = match spec {
        RegressionSpec::Boost(boost) => {
            let fitted = boost::fit_observed(z.view(), fitted_y.view(), groups, boost, observer)?;
            let model = Regression::Boost {
                boost: *boost,
                trees: fitted.model,
            };
            (model, fitted.held_out)
        }
        RegressionSpec::Ridge(ridge) => {
            let fitted = regress::fit(z.view(), fitted_y.view(), groups, ridge)?;
            let model = Regression::Ridge {
                spec: *ridge,
                ridge: fitted.ridge,
            };
            (model, fitted.held_out)
        }
    };
    let mut held_out = held_out.unwrap_or_else(|| fitted_y.clone());
    if let Some(k) = total_anchor {
        for (i, mut row) in held_out.rows_mut().into_iter().enumerate() {
            row[0] = 10f64.powf(row[0] + x[[i, k]]);
        }
    }
    let mut errors = row_errors_of(ds, &held_out, &ward_of_class);
    let group_widths = held_out_widths(ds, &errors);
    mark_covered(ds, &mut errors, &group_widths);
    let report = report(ds, &errors);
    let details = details(ds, &errors, &held_out, &group_widths, &ward_of_class);
    let regressor = WardRegressor {
        inputs: input_indices.iter().map(|&i| ds.names[i].clone()).collect(),
        input_indices,
        scaler,
        regression,
        total_anchor,
        half_widths: report.half_widths,
        cv: report.clone(),
        dataset: dataset.to_string(),
    };
    Ok(Fit {
        regressor,
        report,
        details,
    })
}

fn widths<'a>(errors: impl Iterator<Item = &'a RowErrors> + Clone) -> HalfWidths {
    let q = |f: fn(&RowErrors) -> f64| {
        let values: Vec<f64> = errors.clone().map(f).collect();
        regress::conformal_half_width(&values, COVERAGE)
    };
    HalfWidths {
        rho_d: q(|e| e.rho_d),
        rho_s: q(|e| e.rho_s),
        log10_alpha: q(|e| e.log_alpha),
    }
}

fn row_errors_of(
    ds: &Dataset,
    predictions: &Array2<f64>,
    ward_of_class: &[Ward],
) -> Vec<RowErrors> {
    (0..ds.n_rows())
        .map(|i| row_errors(&predictions.row(i).to_vec(), &ward_of_class[ds.labels[i]]))
        .collect()
}

/// Each illumination's half-widths, sized by the other illuminations' errors only.
fn held_out_widths(ds: &Dataset, errors: &[RowErrors]) -> Vec<HalfWidths> {
    (0..ds.group_names.len())
        .map(|g| {
            let others = errors
                .iter()
                .enumerate()
                .filter(move |(i, _)| ds.groups[*i] != g)
                .map(|(_, e)| e);
            widths(others)
        })
        .collect()
}

/// Mark which intervals (of its group's half-widths) cover each row.
fn mark_covered(ds: &Dataset, errors: &mut [RowErrors], group_widths: &[HalfWidths]) {
    for (i, e) in errors.iter_mut().enumerate() {
        let w = &group_widths[ds.groups[i]];
        e.covered = [
            e.rho_d <= w.rho_d,
            e.rho_s <= w.rho_s,
            e.log_alpha <= w.log10_alpha,
        ];
    }
}

/// The measures over `rows` (none when empty).
fn summarize<'a>(rows: impl Iterator<Item = &'a RowErrors> + Clone) -> Option<Errors> {
    let n = rows.clone().count();
    let share = |f: fn(&RowErrors) -> bool| mean(rows.clone().map(|e| f64::from(u8::from(f(e)))));
    let glossy_alpha = mean(
        rows.clone()
            .filter(|e| e.glossy && e.mirror_right)
            .map(|e| e.log_alpha),
    );
    (n > 0).then(|| Errors {
        n,
        mae_total: mean(rows.clone().map(|e| e.total)),
        mae_rho_d: mean(rows.clone().map(|e| e.rho_d)),
        mae_rho_s: mean(rows.clone().map(|e| e.rho_s)),
        mirror_accuracy: share(|e| e.mirror_right),
        mae_log10_alpha: Some(glossy_alpha).filter(|v| v.is_finite()),
        coverage_rho_d: share(|e| e.covered[0]),
        coverage_rho_s: share(|e| e.covered[1]),
        coverage_alpha: share(|e| e.covered[2]),
    })
}

fn report(ds: &Dataset, errors: &[RowErrors]) -> EstimateReport {
    let none = Errors {
        n: 0,
        mae_total: f64::NAN,
        mae_rho_d: f64::NAN,
        mae_rho_s: f64::NAN,
        mirror_accuracy: f64::NAN,
        mae_log10_alpha: None,
        coverage_rho_d: 0.0,
        coverage_rho_s: 0.0,
        coverage_alpha: 0.0,
    };
    EstimateReport {
        errors: summarize(errors.iter()).unwrap_or(none),
        illuminations: ds.group_names.len(),
        augmented: ds.augmented.iter().filter(|&&a| a).count(),
        half_widths: widths(errors.iter()),
    }
}

fn details(
    ds: &Dataset,
    errors: &[RowErrors],
    held_out: &Array2<f64>,
    group_widths: &[HalfWidths],
    ward_of_class: &[Ward],
) -> EstimateDetails {
    let subset = |keep: &dyn Fn(usize) -> bool| {
        summarize(
            errors
                .iter()
                .enumerate()
                .filter(move |(i, _)| keep(*i))
                .map(|(_, e)| e),
        )
    };
    let illuminations = ds
        .group_names
        .iter()
        .enumerate()
        .filter_map(|(g, name)| {
            subset(&|i| ds.groups[i] == g).map(|errors| IlluminationErrors {
                illumination: name.clone(),
                errors,
            })
        })
        .collect();
    let rows = (0..ds.n_rows())
        .map(|i| HeldOut {
            path: ds.paths[i].clone(),
            illumination: ds.illuminations[i].clone(),
            truth: ward_of_class[ds.labels[i]],
            estimate: estimate_of(&held_out.row(i).to_vec(), &group_widths[ds.groups[i]]),
        })
        .collect();
    EstimateDetails {
        originals: subset(&|i| !ds.augmented[i]),
        augmented: subset(&|i| ds.augmented[i]),
        illuminations,
        rows,
    }
}

impl WardRegressor {
    /// Its errors on `ds` (rows of every extracted feature, e.g. under illuminations it never
    /// saw), whose classes are materials of `materials`, with its own intervals.
    pub fn evaluate(
        &self,
        ds: &Dataset,
        materials: &[Material],
    ) -> Result<(EstimateReport, EstimateDetails), LearnError> {
        let ward_of_class = wards_of(ds, materials)?;
        let outputs: Vec<f64> = (0..ds.n_rows())
            .flat_map(|i| self.predict(&ds.x.row(i).to_vec()))
            .collect();
        let predictions = Array2::from_shape_vec((ds.n_rows(), 4), outputs)
            .map_err(|e| LearnError::InvalidParameter(e.to_string()))?;
        let mut errors = row_errors_of(ds, &predictions, &ward_of_class);
        let widths = vec![self.half_widths; ds.group_names.len()];
        mark_covered(ds, &mut errors, &widths);
        let mut report = report(ds, &errors);
        report.half_widths = self.half_widths;
        let details = details(ds, &errors, &predictions, &widths, &ward_of_class);
        Ok((report, details))
    }
}
