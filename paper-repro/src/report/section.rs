//! A report section as typed data: the paper's statement, what the runs measured, and the
//! verdict by a fixed criterion; rendered to Markdown in one place.

use std::fmt::Write as _;

/// One section of REPORT.md. Every number in it was formatted from a run or a config by the
/// function that built it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Section {
    /// Heading.
    pub title: String,
    /// Plots (paths relative to the report).
    pub plots: Vec<String>,
    /// What the paper says (quoted or paraphrased; `None` for a table or a note).
    pub paper: Option<String>,
    /// What the runs measured; for a table or note, its body.
    pub measured: String,
    /// The verdict and its criterion (`None` for a table or a note).
    pub assessment: Option<String>,
    /// The section's rows of the claims table ([`super::claims`]).
    pub rows: Vec<ClaimRow>,
}

/// One row of the claims table: the claim, the paper's figure, the measured figure and the
/// verdict, each formatted by the function that judged the claim.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ClaimRow {
    /// The claim, short.
    pub claim: String,
    /// The paper's figure.
    pub paper: String,
    /// The measured figure.
    pub measured: String,
    /// The verdict (`**agrees**` ...).
    pub verdict: String,
}

impl Section {
    /// A claim checked against the runs.
    pub fn claim(
        title: impl Into<String>,
        plots: &[&str],
        paper: impl Into<String>,
        measured: String,
        assessment: String,
    ) -> Self {
        Self {
            title: title.into(),
            plots: plots.iter().map(ToString::to_string).collect(),
            paper: Some(paper.into()),
            measured,
            assessment: Some(assessment),
            rows: Vec::new(),
        }
    }

    /// This section with a row of the claims table.
    #[must_use]
    pub fn row(
        mut self,
        claim: impl Into<String>,
        paper: impl Into<String>,
        measured: String,
        verdict: impl Into<String>,
    ) -> Self {
        self.rows.push(ClaimRow {
            claim: claim.into(),
            paper: paper.into(),
            measured,
            verdict: verdict.into(),
        });
        self
    }

    /// A table or a note: a heading and a body.
    pub fn text(title: impl Into<String>, body: String) -> Self {
        Self {
            title: title.into(),
            measured: body,
            ..Self::default()
        }
    }

    /// The Markdown, starting with a blank line and the `##` heading.
    pub fn markdown(&self) -> String {
        let mut s = format!("\n## {}\n\n", self.title);
        for p in &self.plots {
            let _ = writeln!(s, "![{}]({p})\n", self.title);
        }
        match (&self.paper, &self.assessment) {
            (Some(paper), Some(assessment)) => {
                let _ = writeln!(s, "**Paper:** {paper}\n");
                let _ = writeln!(s, "**Measured:** {}\n", self.measured);
                let _ = writeln!(s, "**Assessment:** {assessment}");
            }
            _ => {
                let _ = writeln!(s, "{}", self.measured);
            }
        }
        s
    }
}

/// `**agrees**` or `**does not agree**`.
pub fn verdict(ok: bool) -> &'static str {
    if ok {
        "**agrees**"
    } else {
        "**does not agree**"
    }
}

/// A fraction as a whole percentage.
pub fn pct(x: f64) -> String {
    format!("{:.0} %", 100.0 * x)
}

/// "reduced by 33 %" / "increased by 12 %" for 1 − with/without.
pub fn change(with: f64, without: f64) -> String {
    let red = 1.0 - with / without.max(1e-12);
    if red >= 0.0 {
        format!("reduced by {}", pct(red))
    } else {
        format!("increased by {}", pct(-red))
    }
}
