//! Scenes a benchmark writes for its run: a shipped scene with more tools (`lop-bench latency
//! --devices N`, `lop-bench soak --devices 2`). Each copy is written beside the scene it copies,
//! so the scene's relative paths (meshes, scripts) stay valid, and removed when dropped.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

/// A scene file written beside `path` (its relative paths stay valid), removed when dropped.
pub struct SceneCopy(PathBuf);

impl SceneCopy {
    /// Where the copy is.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for SceneCopy {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// The scene at `path` with `n` tools: its first tool (`[tool]`, or the default tool) and
/// `n − 1` copies named `device2`… whose devices map `spacing_m` further along x each, all
/// playing the scene's mock script. Written beside the scene so its relative paths stay valid.
pub fn scene_with_tools(path: &Path, n: usize, spacing_m: f64) -> Result<SceneCopy> {
    use toml::{Table, Value};
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut scene: Table =
        toml::from_str(&text).with_context(|| format!("{}: not a TOML table", path.display()))?;
    let first = match scene.remove("tool") {
        Some(Value::Table(t)) => t,
        Some(Value::Array(a)) => match a.into_iter().next() {
            Some(Value::Table(t)) => t,
            _ => bail!("{}: its [[tool]] is not a table", path.display()),
        },
        _ => {
            let d = lop_config::ToolSpec::default();
            Table::from_iter([
                ("radius".to_string(), Value::Float(d.radius)),
                ("stiffness".to_string(), Value::Float(d.stiffness)),
            ])
        }
    };
    let workspace = match scene.get("workspace") {
        Some(Value::Table(w)) => w.clone(),
        _ => Table::new(),
    };
    let offset: Vec<f64> = match workspace.get("offset") {
        Some(Value::Array(o)) => o
            .iter()
            .map(|v| {
                v.as_float()
                    .or(v.as_integer().map(|i| i as f64))
                    .unwrap_or(0.0)
            })
            .collect(),
        _ => vec![0.0; 3],
    };
    let script = scene
        .get("device")
        .and_then(|d| d.get("mock_script"))
        .cloned();
    let mut tools = vec![Value::Table(first.clone())];
    for k in 1..n {
        let mut t = first.clone();
        t.insert("name".into(), Value::String(format!("device{}", k + 1)));
        let mut w = workspace.clone();
        let mut o = offset.clone();
        o.resize(3, 0.0);
        o[0] += spacing_m * k as f64;
        w.insert(
            "offset".into(),
            Value::Array(o.into_iter().map(Value::Float).collect()),
        );
        t.insert("workspace".into(), Value::Table(w));
        if let Some(s) = &script {
            t.insert("mock_script".into(), s.clone());
        }
        tools.push(Value::Table(t));
    }
    scene.insert("tool".into(), Value::Array(tools));
    let dir = path.parent().unwrap_or(Path::new("."));
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene");
    let out = dir.join(format!(".{stem}-{n}-devices-{}.toml", std::process::id()));
    std::fs::write(&out, toml::to_string(&scene)?)
        .with_context(|| format!("writing {} (beside the scene)", out.display()))?;
    Ok(SceneCopy(out))
}
