//! Spectra for the reports: a radix-2 FFT and band-limited RMS by FFT masking.

use num_complex::Complex64;

/// In-place iterative radix-2 FFT; `data.len()` must be a power of two.
pub fn fft(data: &mut [Complex64]) {
    let n = data.len();
    debug_assert!(n.is_power_of_two());
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            data.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let w = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI / len as f64);
        for start in (0..n).step_by(len) {
            let mut wk = Complex64::new(1.0, 0.0);
            for k in 0..len / 2 {
                let a = data[start + k];
                let b = data[start + k + len / 2] * wk;
                data[start + k] = a + b;
                data[start + k + len / 2] = a - b;
                wk *= w;
            }
        }
        len <<= 1;
    }
}

/// The spectrum of a real signal sampled every `dt_s`, zero-padded to a power of two: pairs of
/// (frequency [Hz], complex amplitude) for frequencies up to Nyquist.
pub fn spectrum(signal: &[f64], dt_s: f64) -> Vec<(f64, Complex64)> {
    let n = signal.len().next_power_of_two().max(2);
    let mut data: Vec<Complex64> = signal.iter().map(|&v| Complex64::new(v, 0.0)).collect();
    data.resize(n, Complex64::new(0.0, 0.0));
    fft(&mut data);
    (0..=n / 2)
        .map(|k| (k as f64 / (n as f64 * dt_s), data[k]))
        .collect()
}

/// The RMS of the part of `signal` between `lo_hz` (inclusive) and `hi_hz` (exclusive), by
/// Parseval on the zero-padded spectrum, normalised by the signal's own length.
pub fn band_rms(signal: &[f64], dt_s: f64, lo_hz: f64, hi_hz: f64) -> f64 {
    bands_rms(signal, dt_s, &[(lo_hz, hi_hz)])[0]
}

/// [`band_rms`] for several bands from one FFT.
pub fn bands_rms(signal: &[f64], dt_s: f64, bands: &[(f64, f64)]) -> Vec<f64> {
    if signal.is_empty() {
        return vec![0.0; bands.len()];
    }
    let n_pad = signal.len().next_power_of_two().max(2) as f64;
    let spec = spectrum(signal, dt_s);
    let last = spec.len() - 1;
    bands
        .iter()
        .map(|&(lo_hz, hi_hz)| {
            let energy: f64 = spec
                .iter()
                .enumerate()
                .filter(|(_, (f, _))| *f >= lo_hz && *f < hi_hz)
                .map(|(k, (_, c))| {
                    if k == 0 || k == last {
                        c.norm_sqr()
                    } else {
                        2.0 * c.norm_sqr()
                    }
                })
                .sum();
            (energy / (n_pad * signal.len() as f64)).sqrt()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_matches_the_direct_dft() {
        let n = 64;
        let x: Vec<Complex64> = (0..n)
            .map(|k| Complex64::new((k as f64 * 0.37).sin(), (k as f64 * 1.3).cos()))
            .collect();
        let mut y = x.clone();
        fft(&mut y);
        for (k, yk) in y.iter().enumerate() {
            let direct: Complex64 = x
                .iter()
                .enumerate()
                .map(|(j, xj)| {
                    xj * Complex64::from_polar(
                        1.0,
                        -2.0 * std::f64::consts::PI * (j * k) as f64 / n as f64,
                    )
                })
                .sum();
            assert!((yk - direct).norm() < 1e-10);
        }
    }

    #[test]
    fn band_rms_separates_tones() {
        let dt = 1e-3;
        let n = 8192;
        let x: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                2.0 * (2.0 * std::f64::consts::PI * 0.5 * t).sin()
                    + 1.0 * (2.0 * std::f64::consts::PI * 2.5 * t).sin()
            })
            .collect();
        let total = (x.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        let low = band_rms(&x, dt, 0.3, 1.0);
        let high = band_rms(&x, dt, 1.0, 4.0);
        assert!((low - 2.0 / 2f64.sqrt()).abs() < 0.05, "{low}");
        assert!((high - 1.0 / 2f64.sqrt()).abs() < 0.05, "{high}");
        assert!((band_rms(&x, dt, 0.0, 500.1) - total).abs() < 1e-9 * total);
    }
}
