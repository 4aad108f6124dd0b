//! docs/PROFILES.md's "Accepted lint findings" table shows `config/accepted_findings.toml`, row
//! for row: rule, pipeline, profiles and reason.

use tilegraph_profile::accepted::accepted_findings;

#[test]
fn the_accepted_findings_table_in_profiles_md_matches_the_config() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../docs/PROFILES.md"
    ))
    .expect("docs/PROFILES.md");
    let section = doc
        .split("## Accepted lint findings")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("an ## Accepted lint findings section");
    let unquote = |s: &str| s.trim().trim_matches('`').to_string();
    let rows: Vec<(String, String, Vec<String>, String)> = section
        .lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| {
            let cells: Vec<&str> = l.trim().trim_matches('|').split('|').collect();
            assert!(cells.len() >= 4, "row {l:?}");
            (
                unquote(cells[0]),
                unquote(cells[1]),
                cells[2].split(',').map(unquote).collect(),
                cells[3..].join("|").trim().to_string(),
            )
        })
        .collect();
    let config = accepted_findings().unwrap();
    assert_eq!(rows.len(), config.len(), "one row per accepted finding");
    for (row, a) in rows.iter().zip(&config) {
        assert_eq!(row.0, a.rule.name(), "rule");
        assert_eq!(row.1, a.pipeline, "pipeline of {}", a.rule.name());
        assert_eq!(
            row.2,
            a.profiles,
            "profiles of {} {}",
            a.rule.name(),
            a.pipeline
        );
        assert_eq!(
            row.3,
            a.reason,
            "reason of {} {}",
            a.rule.name(),
            a.pipeline
        );
    }
}
