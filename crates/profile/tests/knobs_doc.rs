//! docs/PROFILES.md's knob table lists every knob with its domain and default.

use tilegraph_profile::knobs::{KnobValue, KNOBS};

#[test]
fn the_knob_table_in_profiles_md_matches_the_registry() {
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../docs/PROFILES.md"
    ))
    .expect("docs/PROFILES.md");
    let section = doc
        .split("## Knobs")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("a ## Knobs section");
    let rows: Vec<Vec<String>> = section
        .lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| l.split('|').map(|c| c.trim().to_string()).collect())
        .collect();
    assert_eq!(rows.len(), KNOBS.len(), "one row per knob");
    for k in KNOBS {
        let row = rows
            .iter()
            .find(|r| r[1] == format!("`{}`", k.name))
            .unwrap_or_else(|| panic!("no row for knob {}", k.name));
        let domain: Vec<String> = k.domain.values().iter().map(KnobValue::to_string).collect();
        assert_eq!(row[2], domain.join(", "), "domain of {}", k.name);
        assert_eq!(
            row[3],
            KnobValue::from(k.default).to_string(),
            "default of {}",
            k.name
        );
    }
}
