//! The payloads' JSON Schemas shipped in `docs/schemas/` are the ones the
//! payload types generate (`twin_wire::schema`): a field renamed, added or
//! made optional without `cargo xtask schemas` fails here, and so does a
//! schema file that no payload has any more.

use std::collections::BTreeSet;
use std::path::PathBuf;

fn schema_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/schemas")
}

#[test]
fn every_committed_schema_is_the_generated_one() {
    let dir = schema_dir();
    let schemas = twin_wire::schema::all();
    for s in &schemas {
        let path = dir.join(s.file_name());
        let committed = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("{}: {e}; run `cargo xtask schemas`", path.display()));
        assert!(
            committed == s.file_text(),
            "{} differs from the schema its type generates; run `cargo xtask schemas` and commit it",
            path.display()
        );
    }
    let committed: BTreeSet<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".schema.json"))
        .collect();
    let generated: BTreeSet<String> = schemas.iter().map(|s| s.file_name()).collect();
    assert_eq!(
        committed, generated,
        "schema files without a payload, or payloads without a file; run `cargo xtask schemas`"
    );
}

#[test]
fn every_payload_of_the_contract_has_a_schema() {
    let names: Vec<&str> = twin_wire::schema::all().iter().map(|s| s.name).collect();
    assert_eq!(
        names,
        [
            "gnss",
            "actuators",
            "state",
            "fault",
            "prediction",
            "alarm",
            "finding",
            "stats",
            "daemon-stats"
        ]
    );
}
