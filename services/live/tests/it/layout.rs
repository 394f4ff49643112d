//! The shipped Foxglove layout (`configs/foxglove/exo.json`) shows what
//! issue 17 asks for (θ_e, τ_c, τ_s, the protocol phase, the online K and H
//! estimates, the safety state), and every message path in it names a
//! topic and fields of the recording contract, so it works on a live run
//! and on a recording alike.

use std::collections::BTreeSet;

use serde_json::Value;

fn layout() -> Value {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../configs/foxglove/exo.json"
    );
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Every message path string of the layout's panels.
fn paths(v: &Value, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                match (k.as_str(), x) {
                    ("value" | "topicPath", Value::String(s)) => out.push(s.clone()),
                    _ => paths(x, out),
                }
            }
        }
        Value::Array(a) => a.iter().for_each(|x| paths(x, out)),
        _ => {}
    }
}

/// `"topic"{filter}.field` → (topic, fields named in the filter, field).
fn parse(path: &str) -> (String, Vec<String>, Option<String>) {
    let rest = path.strip_prefix('"').expect("quoted topic");
    let (topic, mut rest) = rest.split_once('"').expect("closing quote");
    let mut filtered = Vec::new();
    while let Some(r) = rest.strip_prefix('{') {
        let (filter, after) = r.split_once('}').expect("closing brace");
        filtered.push(filter.split("==").next().unwrap().trim().to_string());
        rest = after;
    }
    let field = rest.strip_prefix('.').map(str::to_string);
    (topic.to_string(), filtered, field)
}

#[test]
fn every_path_names_a_contract_topic_and_field() {
    let mut all = Vec::new();
    paths(&layout()["configById"], &mut all);
    assert!(all.len() >= 9, "{all:?}");
    let mut shown = BTreeSet::new();
    for p in &all {
        let (topic, filtered, field) = parse(p);
        let row = exo_recording::schema::find(&topic)
            .unwrap_or_else(|| panic!("{p}: {topic} is not a topic of the recording contract"));
        let names: Vec<&str> = row.fields.iter().map(|(n, _)| *n).collect();
        for f in filtered.iter().chain(field.iter()) {
            assert!(names.contains(&f.as_str()), "{p}: {topic} has no field {f}");
        }
        if let Some(f) = field {
            shown.insert(format!("{topic}.{f}"));
        }
    }
    for wanted in [
        "exo/sensor.theta_e",
        "exo/sensor.tau_c",
        "exo/sensor.tau_s",
        "exo/protocol.phase",
        "exo/identifier/estimate.k_h",
        "exo/identifier/estimate.h_h",
        "exo/command.mode",
        "exo/sensor.status",
    ] {
        assert!(shown.contains(wanted), "the layout does not show {wanted}");
    }
}

#[test]
fn every_panel_is_placed_and_every_placed_panel_configured() {
    let l = layout();
    let configured: BTreeSet<String> = l["configById"]
        .as_object()
        .unwrap()
        .keys()
        .cloned()
        .collect();
    fn leaves(v: &Value, out: &mut BTreeSet<String>) {
        match v {
            Value::String(s) => {
                out.insert(s.clone());
            }
            Value::Object(m) => {
                for k in ["first", "second"] {
                    leaves(&m[k], out);
                }
            }
            _ => panic!("not a mosaic node: {v}"),
        }
    }
    let mut placed = BTreeSet::new();
    leaves(&l["layout"], &mut placed);
    assert_eq!(placed, configured);
}
