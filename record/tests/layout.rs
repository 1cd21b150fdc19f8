//! The shipped Foxglove/Lichtblick layout (`record/layouts/mmt.json`) names topics the recording
//! has and fields their schemas define, so no plot in it is silently empty.
#![allow(clippy::unwrap_used)]

use record::topic_schema;

/// The field names a JSON Schema defines anywhere (its `properties`, nested definitions
/// included).
fn fields(schema: &serde_json::Value, out: &mut Vec<String>) {
    match schema {
        serde_json::Value::Object(map) => {
            if let Some(serde_json::Value::Object(props)) = map.get("properties") {
                out.extend(props.keys().cloned());
            }
            for v in map.values() {
                fields(v, out);
            }
        }
        serde_json::Value::Array(items) => items.iter().for_each(|v| fields(v, out)),
        _ => {}
    }
}

#[test]
fn the_layouts_plots_name_recorded_topics_and_fields() {
    let text = include_str!("../layouts/mmt.json");
    let layout: serde_json::Value = serde_json::from_str(text).unwrap();
    let mut paths = Vec::new();
    for panel in layout["configById"].as_object().unwrap().values() {
        for p in panel["paths"].as_array().into_iter().flatten() {
            paths.push(p["value"].as_str().unwrap().to_owned());
        }
        if let Some(t) = panel["topicToRender"].as_str() {
            assert!(topic_schema(t).is_some(), "log topic {t}");
        }
        for t in panel["topics"]
            .as_object()
            .into_iter()
            .flatten()
            .map(|(t, _)| t)
        {
            assert!(topic_schema(t).is_some(), "3-D topic {t}");
        }
    }
    assert!(paths.len() >= 8, "{paths:?}");
    for path in paths {
        let (topic, rest) = path.split_once('.').unwrap();
        let schema = topic_schema(topic).unwrap_or_else(|| panic!("{path}: no topic {topic}"));
        assert_eq!(schema.schema_encoding, "jsonschema", "{path}");
        let mut known = Vec::new();
        fields(&serde_json::from_slice(&schema.data).unwrap(), &mut known);
        for field in rest.split('.') {
            let name = field.split('[').next().unwrap();
            assert!(known.iter().any(|k| k == name), "{path}: no field {name}");
        }
    }
}
