//! Model-file loading on arbitrary bytes: `ModelFile::from_json` refuses or accepts, never
//! panics; an accepted model builds its extractor and classifies without panicking. The
//! input is also tried "resealed" (its `sha256` recomputed), so that mutations get past the
//! checksum into the schema, consistency and self-test checks.
#![no_main]

use libfuzzer_sys::fuzz_target;
use reflectance_core::model::{ModelFile, checksum};
use reflectance::LoadedModel;
use serde_json::Value;

fn exercise(model: ModelFile) {
    let n = model.features.config.names().len();
    for fill in [0.0, 0.5, 1e6] {
        let row = vec![fill; n];
        if let Ok(z) = model.classifier.transform(&row) {
            let out = model.classifier.classify_transformed(&z);
            assert!(out.class < model.classifier.classes().len());
        }
        let _ = model.nearest(&row, 3);
    }
    let _ = LoadedModel::new(model);
}

fuzz_target!(|data: &[u8]| {
    if let Ok(model) = ModelFile::from_json(data) {
        exercise(model);
    }
    let Ok(mut value) = serde_json::from_slice::<Value>(data) else {
        return;
    };
    if !value.is_object() {
        return;
    }
    let sum = checksum(value.clone());
    value["sha256"] = Value::String(sum);
    let bytes = serde_json::to_vec(&value).expect("serializable");
    if let Ok(model) = ModelFile::from_json(&bytes) {
        exercise(model);
    }
});
