//! The HTML page of a `--report DIR`: one layout for every diagnosis (the verdict from the one
//! [`Findings`] wording, a "where" list, a candidate table, the figures, the rule), so the rig
//! and the axis reports differ only in their evidence.

use forcemap_math::diagnose::{Findings, ParameterValue, Verdict};

/// Text for HTML element content and attribute values.
pub fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Parameters as `name = value +/- std` (the std when the fit gave one).
pub fn parameters_text(list: &[ParameterValue]) -> String {
    list.iter()
        .map(|p| match p.std {
            Some(s) => format!("{} = {:.4e} +/- {:.1e}", p.name, p.value, s),
            None => format!("{} = {:.4e}", p.name, p.value),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The whole model with an effect, as refitted: the baseline's coefficients refitted beside the
/// effect, then what the effect added (`k = ..., c = ...; alpha = ..., yield_m = ...`).
pub fn model_with_effect_text(
    baseline: &str,
    effect: &str,
    refitted: &[ParameterValue],
    added: &[ParameterValue],
) -> String {
    format!(
        "model {baseline} + {effect}, refitted: {}; {}",
        parameters_text(refitted),
        parameters_text(added)
    )
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1250px;margin:auto}table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}td:first-child{text-align:left}td.text{text-align:left}";

/// A report page, built section by section; every text argument is escaped here.
pub struct HtmlReport {
    html: String,
}

impl HtmlReport {
    /// A page titled `title`, with `title` as its heading.
    pub fn new(title: &str) -> HtmlReport {
        let t = html_escape(title);
        HtmlReport {
            html: format!(
                "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>forcemap: {t}</title>\n<style>{STYLE}</style></head><body>\n<h1>{t}</h1>\n"
            ),
        }
    }

    pub fn paragraph(&mut self, text: &str) {
        self.html
            .push_str(&format!("<p>{}</p>\n", html_escape(text)));
    }

    /// The verdict heading and the gap figures, in the words of [`Findings`].
    pub fn verdict(&mut self, f: &Findings) {
        let verdict = match (f.verdict, f.top_effect) {
            (Verdict::Explained, Some(e)) => format!("explained by <b>{}</b>", e.name()),
            (Verdict::ExplainedInPart, Some(e)) => {
                format!("explained in part by <b>{}</b>", e.name())
            }
            (v, _) => v.name().to_string(),
        };
        let best = f.best_candidate.map_or(String::new(), |e| {
            format!(", {:.2} % with {}", f.gap_after_percent, e.name())
        });
        self.html.push_str(&format!(
            "<h2>Verdict: {verdict}</h2>\n<p>{}: {:.2} % with the baseline{}; floor {:.2} %.</p>\n",
            html_escape(&capitalised(f.evidence.measure())),
            f.gap_before_percent,
            html_escape(&best),
            f.floor_percent
        ));
    }

    /// A section with a bulleted list.
    pub fn list(&mut self, heading: &str, items: &[String]) {
        self.html
            .push_str(&format!("<h2>{}</h2>\n<ul>\n", html_escape(heading)));
        for s in items {
            self.html
                .push_str(&format!("<li>{}</li>\n", html_escape(s)));
        }
        self.html.push_str("</ul>\n");
    }

    /// A section with a table; the last column is text (left-aligned).
    pub fn table(&mut self, heading: &str, header: &[&str], rows: &[Vec<String>]) {
        self.html
            .push_str(&format!("<h2>{}</h2>\n<table><tr>", html_escape(heading)));
        for h in header {
            self.html.push_str(&format!("<th>{}</th>", html_escape(h)));
        }
        self.html.push_str("</tr>\n");
        for row in rows {
            self.html.push_str("<tr>");
            for (i, cell) in row.iter().enumerate() {
                let class = if i + 1 == row.len() && i > 0 {
                    " class=\"text\""
                } else {
                    ""
                };
                self.html
                    .push_str(&format!("<td{class}>{}</td>", html_escape(cell)));
            }
            self.html.push_str("</tr>\n");
        }
        self.html.push_str("</table>\n");
    }

    /// Figures as (file in the report directory, caption).
    pub fn figures<S: AsRef<str>>(&mut self, figures: &[(S, String)]) {
        for (file, caption) in figures {
            let c = html_escape(caption);
            self.html.push_str(&format!(
                "<h3>{c}</h3>\n<img src=\"{}\" alt=\"{c}\">\n",
                html_escape(file.as_ref())
            ));
        }
    }

    /// The page, closed with the verdict rule.
    pub fn finish(mut self, rule: &str) -> String {
        self.html.push_str(&format!(
            "<p>Rule: {}</p>\n</body></html>\n",
            html_escape(rule)
        ));
        self.html
    }
}

fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map_or(String::new(), |f| f.to_uppercase().chain(c).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use forcemap_math::diagnose::{Effect, Evidence, TopCandidate};

    #[test]
    fn a_page_escapes_its_text_and_states_the_verdict_and_rule() {
        let f = Findings::decide(
            Evidence::HeldOutNmse,
            14.8,
            0.5,
            Some(TopCandidate {
                effect: Effect::CoulombFriction,
                gap_after_percent: 0.96,
                significant: true,
            }),
        );
        let mut r = HtmlReport::new("Gap diagnosis: baseline <linear>");
        r.verdict(&f);
        r.list("Where", &["x < 0 & y".into()]);
        r.table(
            "Candidates",
            &["effect", "signature"],
            &[vec!["a".into(), "b<".into()]],
        );
        r.figures(&[("s.svg", "cap".to_string())]);
        let html = r.finish(&f.rule);
        assert!(html.contains("<h1>Gap diagnosis: baseline &lt;linear&gt;</h1>"));
        assert!(html.contains("<h2>Verdict: explained by <b>coulomb_friction</b></h2>"));
        assert!(html.contains(
            "Held-out NMSE of the mass acceleration: 14.80 % with the baseline, 0.96 % with coulomb_friction; floor 0.50 %."
        ));
        assert!(html.contains("<li>x &lt; 0 &amp; y</li>"));
        assert!(html.contains("<td>a</td><td class=\"text\">b&lt;</td>"));
        assert!(html.contains("<img src=\"s.svg\" alt=\"cap\">"));
        assert!(html.ends_with(&format!(
            "<p>Rule: {}</p>\n</body></html>\n",
            html_escape(&f.rule)
        )));
    }
}
