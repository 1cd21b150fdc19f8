//! The series as CSV, and back: one row per operator tick, what the plots and a later look at
//! the run need. The state-sync columns and the telerobot's per-tick stability are not in it.

use crate::Series;

/// The CSV header, in column order.
pub const CSV_HEADER: &str = "t_s,x_m,y_m,z_m,measured_x_n,measured_y_n,measured_z_n,rendered_x_n,rendered_y_n,rendered_z_n,rendered_remote_x_n,rendered_remote_y_n,rendered_remote_z_n,contact_true,contact_local,contact_remote,rendering,true_x_n,true_y_n,true_z_n";

/// Why a CSV text is not a series.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CsvError {
    /// The first line is not [`CSV_HEADER`].
    #[error("line 1: the header is not that of a series (expected `{CSV_HEADER}`)")]
    Header,
    /// A row has another number of columns.
    #[error("line {line}: {found} columns, expected 20")]
    Columns {
        /// 1-based line.
        line: usize,
        /// Columns found.
        found: usize,
    },
    /// A value does not parse as its column's type.
    #[error("line {line}, column {column} ({name}): '{value}' is not {expected}")]
    Value {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The column's name.
        name: &'static str,
        /// The text found.
        value: String,
        /// What was expected.
        expected: &'static str,
    },
}

impl Series {
    /// The series as CSV: one row per operator tick.
    pub fn to_csv(&self) -> String {
        use std::fmt::Write as _;
        let mut out = String::with_capacity(self.len() * 200);
        out.push_str(CSV_HEADER);
        out.push('\n');
        let b = |v: bool| if v { 1 } else { 0 };
        for i in 0..self.len() {
            let p = self.position[i];
            let m = self.measured[i].map_or([f64::NAN; 3], |m| m);
            let r = self.rendered[i];
            let q = self.rendered_remote[i];
            let t = self.true_force[i].map_or([f64::NAN; 3], |t| t);
            let _ = writeln!(
                out,
                "{:.3},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{},{},{},{},{:.5},{:.5},{:.5}",
                i as f64 * self.dt_s(),
                p[0],
                p[1],
                p[2],
                m[0],
                m[1],
                m[2],
                r[0],
                r[1],
                r[2],
                q[0],
                q[1],
                q[2],
                self.contact_true[i].map_or(-1, b),
                b(self.contact_local[i]),
                b(self.contact_remote[i]),
                rendering_code(self.rendering[i], self.reduced.get(i).copied()),
                t[0],
                t[1],
                t[2],
            );
        }
        out
    }

    /// A series from its CSV ([`Series::to_csv`]), with the period and plot axes it was
    /// recorded with (the CSV does not carry them). Forces come back to the CSV's 10 µN, positions
    /// to its 1 µm; the columns the CSV leaves out are empty.
    pub fn from_csv(
        text: &str,
        period_ns: i64,
        axis: [f64; 3],
        normal: [f64; 3],
    ) -> Result<Series, CsvError> {
        let mut lines = text.lines();
        if lines.next() != Some(CSV_HEADER) {
            return Err(CsvError::Header);
        }
        let rows: Vec<&str> = lines.filter(|l| !l.is_empty()).collect();
        let mut s = Series::with_capacity(rows.len(), axis, normal, period_ns);
        for (i, line) in rows.iter().enumerate() {
            let row = Row::parse(line, i + 2)?;
            s.position.push(row.vector(1)?);
            s.measured[i] = row.optional_vector(4)?;
            s.rendered.push(row.vector(7)?);
            s.rendered_remote.push(row.vector(10)?);
            s.contact_true[i] = match row.integer(13)? {
                -1 => None,
                v => Some(v == 1),
            };
            s.contact_local.push(row.integer(14)? == 1);
            s.contact_remote.push(row.integer(15)? == 1);
            let (rendering, reduced) = row.rendering(16)?;
            s.rendering.push(rendering);
            s.reduced.push(reduced);
            s.true_force[i] = row.optional_vector(17)?;
            s.operator_state.push([None; 2]);
        }
        Ok(s)
    }
}

/// The `rendering` column: 0 no model, 1 a whole model, 2 the telerobot's reduced first model
/// (files written before the reduced model read as 0 and 1).
fn rendering_code(rendering: bool, reduced: Option<bool>) -> u8 {
    match (rendering, reduced) {
        (false, _) => 0,
        (true, Some(true)) => 2,
        (true, _) => 1,
    }
}

/// One CSV row, split.
struct Row<'a> {
    line: usize,
    cells: Vec<&'a str>,
}

const NAMES: [&str; 20] = [
    "t_s",
    "x_m",
    "y_m",
    "z_m",
    "measured_x_n",
    "measured_y_n",
    "measured_z_n",
    "rendered_x_n",
    "rendered_y_n",
    "rendered_z_n",
    "rendered_remote_x_n",
    "rendered_remote_y_n",
    "rendered_remote_z_n",
    "contact_true",
    "contact_local",
    "contact_remote",
    "rendering",
    "true_x_n",
    "true_y_n",
    "true_z_n",
];

impl<'a> Row<'a> {
    fn parse(text: &'a str, line: usize) -> Result<Row<'a>, CsvError> {
        let cells: Vec<&str> = text.split(',').collect();
        if cells.len() != NAMES.len() {
            return Err(CsvError::Columns {
                line,
                found: cells.len(),
            });
        }
        Ok(Row { line, cells })
    }

    fn error(&self, column: usize, expected: &'static str) -> CsvError {
        CsvError::Value {
            line: self.line,
            column: column + 1,
            name: NAMES[column],
            value: self.cells[column].to_owned(),
            expected,
        }
    }

    /// A number; NaN allowed (the CSV's "none").
    fn number(&self, column: usize) -> Result<f64, CsvError> {
        self.cells[column]
            .parse::<f64>()
            .ok()
            .filter(|v| !v.is_infinite())
            .ok_or_else(|| self.error(column, "a number"))
    }

    fn vector(&self, first: usize) -> Result<[f64; 3], CsvError> {
        let v = [
            self.number(first)?,
            self.number(first + 1)?,
            self.number(first + 2)?,
        ];
        match v.iter().position(|c| c.is_nan()) {
            Some(k) => Err(self.error(first + k, "a finite number")),
            None => Ok(v),
        }
    }

    /// Three numbers, all NaN for "none".
    fn optional_vector(&self, first: usize) -> Result<Option<[f64; 3]>, CsvError> {
        let v = [
            self.number(first)?,
            self.number(first + 1)?,
            self.number(first + 2)?,
        ];
        if v.iter().all(|c| c.is_nan()) {
            return Ok(None);
        }
        match v.iter().position(|c| c.is_nan()) {
            Some(k) => Err(self.error(first + k, "a finite number (or NaN in all three)")),
            None => Ok(Some(v)),
        }
    }

    /// The `rendering` column ([`rendering_code`]): whether a model renders, and whether it is
    /// the reduced one.
    fn rendering(&self, column: usize) -> Result<(bool, bool), CsvError> {
        match self.cells[column] {
            "0" => Ok((false, false)),
            "1" => Ok((true, false)),
            "2" => Ok((true, true)),
            _ => Err(self.error(column, "0, 1 or 2")),
        }
    }

    /// -1, 0 or 1.
    fn integer(&self, column: usize) -> Result<i8, CsvError> {
        match self.cells[column] {
            "-1" => Ok(-1),
            "0" => Ok(0),
            "1" => Ok(1),
            _ => Err(self.error(column, "-1, 0 or 1")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series() -> Series {
        let mut s = Series::with_capacity(3, [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], 1_000_000);
        for k in 0..3 {
            s.position.push([0.001 * k as f64, 0.5, -0.002]);
            s.rendered.push([0.1, 1.25 * k as f64, 3.0]);
            s.rendered_remote.push([0.0; 3]);
            s.contact_local.push(k > 0);
            s.contact_remote.push(false);
            s.rendering.push(k >= 1);
            s.reduced.push(k == 1);
            s.operator_state.push([None; 2]);
        }
        s.measured[1] = Some([0.5, -1.0, 2.25]);
        s.contact_true[1] = Some(true);
        s.contact_true[2] = Some(false);
        s.true_force[2] = Some([0.0, 0.0, 1.5]);
        s
    }

    #[test]
    fn a_series_comes_back_from_its_csv() {
        let s = series();
        let back = Series::from_csv(&s.to_csv(), s.period_ns, s.axis, s.normal).unwrap();
        assert_eq!(back.len(), 3);
        assert_eq!(back.position, s.position);
        assert_eq!(back.rendered, s.rendered);
        assert_eq!(back.measured, s.measured);
        assert_eq!(back.true_force, s.true_force);
        assert_eq!(back.contact_true, s.contact_true);
        assert_eq!(back.contact_local, s.contact_local);
        assert_eq!(back.rendering, s.rendering);
        assert_eq!(back.reduced, s.reduced);
        assert_eq!(back.whole_model_start(), Some(2));
        assert_eq!(back.to_csv(), s.to_csv());
    }

    #[test]
    fn a_bad_csv_names_the_line_the_column_and_the_value() {
        let s = series().to_csv();
        assert_eq!(
            Series::from_csv("a,b\n", 1, [0.0; 3], [0.0; 3]).unwrap_err(),
            CsvError::Header
        );
        let mut lines: Vec<String> = s.lines().map(str::to_owned).collect();
        let cut = lines[1].rfind(',').unwrap();
        lines[1].truncate(cut);
        let short = lines.join("\n");
        assert!(matches!(
            Series::from_csv(&short, 1, [0.0; 3], [0.0; 3]),
            Err(CsvError::Columns { found: 19, .. })
        ));
        let bad = s.replacen("0.500000", "half", 1);
        let e = Series::from_csv(&bad, 1, [0.0; 3], [0.0; 3]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 2, column 3 (y_m): 'half' is not a number"
        );
        let partial = s.replacen("0.50000,-1.00000", "NaN,-1.00000", 1);
        let e = Series::from_csv(&partial, 1, [0.0; 3], [0.0; 3]).unwrap_err();
        assert!(e.to_string().contains("measured_x_n"), "{e}");
    }
}
