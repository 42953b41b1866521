//! Distribution quantiles the tests of adjusted results need, stated once: every σ0 bound,
//! honest-σ band and range study uses these.

/// The quantile of χ² with `k` degrees of freedom at the standard normal quantile `z`
/// (Wilson–Hilferty: `k (1 − a + z √a)³`, a = 2/(9k); within 1 % from k = 10 at z = ±1.96,
/// within 0.5 % of the tabulated 99 % quantile from k = 3, within 2 % of the 1 % quantile
/// from k = 10). Clamped at 0 for a lower
/// quantile of very few degrees of freedom.
pub fn chi2_quantile(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).max(0.0).powi(3)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tabulated χ²₀.₉₉(k) and χ²₀.₀₁(k) (NIST/SEMATECH e-Handbook, table 1.3.6.7.4).
    #[test]
    fn quantiles_against_the_table() {
        let z99 = 2.326_347_874;
        for (k, q) in [
            (3.0, 11.345),
            (6.0, 16.812),
            (15.0, 30.578),
            (27.0, 46.963),
            (100.0, 135.807),
        ] {
            let a = chi2_quantile(k, z99);
            assert!(
                (a - q).abs() / q < 0.005,
                "χ²₀.₉₉({k}) = {a}, tabulated {q}"
            );
        }
        for (k, q) in [(10.0, 2.558), (30.0, 14.953), (100.0, 70.065)] {
            let a = chi2_quantile(k, -z99);
            assert!((a - q).abs() / q < 0.02, "χ²₀.₀₁({k}) = {a}, tabulated {q}");
        }
    }
}
