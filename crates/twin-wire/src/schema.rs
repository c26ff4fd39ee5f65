//! JSON Schemas (draft 2020-12) of every payload of the contract, generated
//! from the payload types themselves, and the files they are shipped as
//! (`docs/schemas/{name}.schema.json`, written by `cargo xtask schemas`).
//!
//! An input's schema says what the daemon accepts (serde's deserialising
//! shape: optional fields may be left out, unknown fields are ignored, and
//! the ranges the validation of [`crate::messages`] holds a fix to). An
//! output's schema says exactly what the daemon emits (serde's serialising
//! shape: every field the type always writes is required, an optional one
//! is `null` when unknown, enums are their snake-case strings, and no field
//! outside the schema is allowed).

use schemars::generate::SchemaSettings;
use schemars::{JsonSchema, Schema};
use serde_json::Value;

use crate::messages::{ActuatorsMessage, GnssMessage};
use crate::outputs::{
    AlarmMessage, DaemonStatsMessage, FaultMessage, FindingsMessage, PredictionMessage,
    StateMessage, StatsMessage,
};

/// Which way a payload goes, and so which of serde's shapes its schema
/// describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Into the daemon: what it accepts.
    Input,
    /// Out of the daemon: what it emits.
    Output,
}

/// One payload's schema.
#[derive(Debug, Clone)]
pub struct PayloadSchema {
    /// The file's stem: `docs/schemas/{name}.schema.json`.
    pub name: &'static str,
    /// The key (under the prefix) the payload travels on.
    pub key: &'static str,
    /// Input or output.
    pub direction: Direction,
    /// The schema.
    pub schema: Value,
}

impl PayloadSchema {
    /// The file name: `{name}.schema.json`.
    pub fn file_name(&self) -> String {
        format!("{}.schema.json", self.name)
    }

    /// The file's text: the schema as indented JSON with a final newline.
    pub fn file_text(&self) -> String {
        let mut text = serde_json::to_string_pretty(&self.schema).expect("a schema is plain JSON");
        text.push('\n');
        text
    }
}

/// Forbids properties outside the schema on every object that lists its
/// properties (a map, which lists none, keeps its `additionalProperties`).
fn closed_objects(schema: &mut Schema) {
    if let Some(object) = schema.as_object_mut()
        && object.contains_key("properties")
        && !object.contains_key("additionalProperties")
    {
        object.insert("additionalProperties".to_string(), Value::Bool(false));
    }
    schemars::transform::transform_subschemas(&mut closed_objects, schema);
}

fn generate<T: JsonSchema>(
    name: &'static str,
    key: &'static str,
    direction: Direction,
) -> PayloadSchema {
    let settings = SchemaSettings::draft2020_12();
    let settings = match direction {
        Direction::Input => settings.for_deserialize(),
        Direction::Output => settings.for_serialize().with_transform(closed_objects),
    };
    let mut schema = settings.into_generator().into_root_schema_for::<T>();
    if let Some(object) = schema.as_object_mut() {
        object.insert(
            "$id".to_string(),
            Value::from(format!("{name}.schema.json")),
        );
    }
    PayloadSchema {
        name,
        key,
        direction,
        schema: schema.to_value(),
    }
}

/// Every payload's schema, inputs first, in the order of the contract
/// table (docs/contracts.md).
pub fn all() -> Vec<PayloadSchema> {
    use Direction::{Input, Output};
    vec![
        generate::<GnssMessage>("gnss", "{vessel}/gnss", Input),
        generate::<ActuatorsMessage>("actuators", "{vessel}/actuators", Input),
        generate::<StateMessage>("state", "{vessel}/twin/state", Output),
        generate::<FaultMessage>("fault", "{vessel}/twin/fault", Output),
        generate::<PredictionMessage>("prediction", "{vessel}/twin/prediction", Output),
        generate::<AlarmMessage>("alarm", "{vessel}/twin/alarm", Output),
        generate::<FindingsMessage>("finding", "{vessel}/twin/finding", Output),
        generate::<StatsMessage>("stats", "{vessel}/twin/stats", Output),
        generate::<DaemonStatsMessage>("daemon-stats", "@twind/{daemon}/stats", Output),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn schema(name: &str) -> Value {
        all()
            .into_iter()
            .find(|s| s.name == name)
            .expect("a schema of that name")
            .schema
    }

    #[test]
    fn an_output_requires_its_always_written_fields_and_allows_no_other() {
        let state = schema("state");
        let required: Vec<&str> = state["required"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        for field in ["vessel", "time", "heading_rad", "current", "stale", "sigma"] {
            assert!(
                required.contains(&field),
                "{field} not required: {required:?}"
            );
        }
        assert_eq!(state["additionalProperties"], Value::Bool(false));
        // The stats' NMEA block is left out when empty: not required.
        let stats = schema("stats");
        let required = stats["required"].as_array().unwrap();
        assert!(!required.contains(&Value::from("nmea")), "{required:?}");
        assert!(required.contains(&Value::from("received")), "{required:?}");
    }

    #[test]
    fn an_input_requires_only_what_the_daemon_needs() {
        let gnss = schema("gnss");
        let mut required: Vec<&str> = gnss["required"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        required.sort_unstable();
        assert_eq!(
            required,
            ["cog_rad", "lat_deg", "lon_deg", "sog_mps", "time"]
        );
        assert!(
            gnss.get("additionalProperties").is_none(),
            "unknown fields are ignored"
        );
        assert_eq!(gnss["properties"]["lat_deg"]["maximum"], Value::from(90.0));
    }
}
