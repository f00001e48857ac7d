//! The claims table: one row per paper claim (the claim, the paper's figure, the measured
//! figure, the verdict), made from the rows the report's sections carry. One function
//! writes it for both REPORT.md (its "Claims" section) and `claims.md` (the README's
//! block between `<!-- claims:begin -->` and `<!-- claims:end -->`, checked by
//! `tools/readme-claims.sh`).

use super::section::Section;
use std::fmt::Write as _;

/// A table cell: no line break, no unescaped `|`.
fn cell(s: &str) -> String {
    s.replace('\n', " ").replace('|', "\\|").trim().to_string()
}

/// The claims table of `sections`, in their order, as Markdown.
#[must_use]
pub fn table(sections: &[Section]) -> String {
    let mut t = String::from("| claim | paper | measured | verdict |\n|---|---|---|---|\n");
    for r in sections.iter().flat_map(|s| &s.rows) {
        let _ = writeln!(
            t,
            "| {} | {} | {} | {} |",
            cell(&r.claim),
            cell(&r.paper),
            cell(&r.measured),
            cell(&r.verdict)
        );
    }
    t
}

/// REPORT.md's claims section: [`table`] under a heading.
#[must_use]
pub fn section(sections: &[Section]) -> Section {
    Section::text(
        "Claims",
        format!(
            "Each paper claim, the paper's figure, the measured one and the verdict; the \
             sections below give the criteria and the evidence. The same table is \
             `claims.md`.\n\n{}",
            table(sections)
        ),
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn each_row_is_one_line_with_its_pipes_escaped() {
        let s =
            Section::text("t", String::new()).row("a | b", "p", "m\nn".to_string(), "**agrees**");
        let t = table(&[s.clone(), s]);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 4, "{t}");
        assert_eq!(lines[2], "| a \\| b | p | m n | **agrees** |");
        assert!(section(&[]).markdown().contains("| claim | paper |"));
    }
}
