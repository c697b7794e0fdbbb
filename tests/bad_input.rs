//! Malformed scene files, OBJ meshes and textures from tests/data/bad: each must be
//! rejected with its specific error variant, a message naming the file, the line and the
//! key or statement, and never a panic.

use raypack::rng::SplitMix64;
use raypack::scene::{ObjError, SceneError, TextureError, file, obj, texture};
use std::error::Error;
use std::path::PathBuf;

fn data(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/bad")
        .join(rel)
}

/// The error's message followed by those of its sources, as the CLI prints it.
fn chain(e: &dyn Error) -> String {
    let mut s = e.to_string();
    let mut source = e.source();
    while let Some(c) = source {
        s.push_str(": ");
        s.push_str(&c.to_string());
        source = c.source();
    }
    s
}

fn scene_err(name: &str) -> (SceneError, String) {
    let path = data(&format!("scene/{name}"));
    match file::load(&path) {
        Ok(_) => panic!("{} loaded, but it is malformed", path.display()),
        Err(e) => {
            let msg = chain(&e);
            assert!(
                raypack::is_input_error(&e),
                "{name}: not classed as bad input"
            );
            (e, msg)
        }
    }
}

/// Asserts that `msg` starts with `name:line:` and contains every `parts`.
fn assert_names(msg: &str, name: &str, line: usize, parts: &[&str]) {
    let at = format!("{name}:{line}: ");
    assert!(msg.contains(&at), "`{msg}` does not name `{at}`");
    for p in parts {
        assert!(msg.contains(p), "`{msg}` lacks `{p}`");
    }
}

macro_rules! scene_case {
    ($test:ident, $file:literal, $pat:pat $(if $guard:expr)?, $line:expr, [$($part:expr),*]) => {
        #[test]
        fn $test() {
            let (e, msg) = scene_err($file);
            assert!(matches!(e, $pat $(if $guard)?), "{}: unexpected variant: {e:?}", $file);
            assert_names(&msg, $file, $line, &[$($part),*]);
        }
    };
}

scene_case!(unknown_key_suggests_nearest, "unknown_key.toml",
    SceneError::UnknownKey { ref suggestion, .. } if suggestion.as_deref() == Some("radius"),
    7, ["spheres[0].radus", "did you mean `radius`"]);
scene_case!(unknown_section_suggests_nearest, "unknown_section.toml",
    SceneError::UnknownKey { ref suggestion, .. } if suggestion.as_deref() == Some("materials"),
    9, ["materals"]);
scene_case!(
    syntax_error_names_line,
    "syntax.toml",
    SceneError::Syntax { .. },
    3,
    ["expected value"]
);
scene_case!(
    duplicate_key_is_syntax_error,
    "duplicate_key.toml",
    SceneError::Syntax { .. },
    4,
    ["duplicate"]
);
scene_case!(
    wrong_type,
    "wrong_type.toml",
    SceneError::Invalid { .. },
    7,
    ["spheres[0].radius", "expected a number, found string"]
);
scene_case!(
    wrong_vector_length,
    "wrong_length.toml",
    SceneError::Invalid { .. },
    6,
    ["spheres[0].center", "array of 3 numbers"]
);
scene_case!(
    section_of_wrong_type,
    "section_not_table.toml",
    SceneError::Invalid { .. },
    1,
    ["camera", "expected a table"]
);
scene_case!(
    negative_radius,
    "negative_radius.toml",
    SceneError::Invalid { .. },
    7,
    ["spheres[0].radius", "must be > 0"]
);
scene_case!(
    zero_radius,
    "zero_radius.toml",
    SceneError::Invalid { .. },
    7,
    ["spheres[0].radius", "must be > 0"]
);
scene_case!(
    zero_width,
    "zero_width.toml",
    SceneError::Invalid { .. },
    6,
    ["render.width", "out of range"]
);
scene_case!(
    absurd_resolution,
    "absurd_resolution.toml",
    SceneError::Invalid { .. },
    7,
    ["render.height", "pixels"]
);
scene_case!(
    huge_integer,
    "huge_integer.toml",
    SceneError::Invalid { .. },
    6,
    ["render.width", "too large"]
);
scene_case!(
    nan_coordinate,
    "nan.toml",
    SceneError::Invalid { .. },
    6,
    ["spheres[0].center", "not a finite number"]
);
scene_case!(
    infinite_vfov,
    "inf_vfov.toml",
    SceneError::Invalid { .. },
    4,
    ["camera.vfov", "not a finite number"]
);
scene_case!(
    f32_overflow,
    "f32_overflow.toml",
    SceneError::Invalid { .. },
    7,
    ["spheres[0].radius", "not a finite number"]
);
scene_case!(
    ior_zero,
    "ior_zero.toml",
    SceneError::Invalid { .. },
    7,
    ["materials.glass.ior", "must be > 0"]
);
scene_case!(
    ior_negative,
    "ior_negative.toml",
    SceneError::Invalid { .. },
    6,
    ["materials.glass.ior"]
);
scene_case!(
    depth_too_large,
    "depth_too_large.toml",
    SceneError::Invalid { .. },
    6,
    ["render.max_depth", "0 to 64"]
);
scene_case!(
    light_samples_too_large,
    "light_samples_too_large.toml",
    SceneError::Invalid { .. },
    13,
    ["lights[0].samples", "1 to 4096"]
);
scene_case!(
    glossy_samples_zero,
    "glossy_samples_zero.toml",
    SceneError::Invalid { .. },
    6,
    ["render.glossy_samples"]
);
scene_case!(
    zero_area_light,
    "zero_area_light.toml",
    SceneError::Invalid { .. },
    13,
    ["lights[0].edge_v", "zero area"]
);
scene_case!(
    zero_size_light,
    "zero_size_light.toml",
    SceneError::Invalid { .. },
    12,
    ["lights[0].size", "zero area"]
);
scene_case!(
    up_parallel_to_view,
    "up_parallel.toml",
    SceneError::Invalid { .. },
    4,
    ["camera.up", "parallel"]
);
scene_case!(
    eye_equals_target,
    "eye_is_target.toml",
    SceneError::Invalid { .. },
    3,
    ["camera.target", "equals `eye`"]
);
scene_case!(
    eye_too_far_from_target_overflows,
    "eye_far_from_target.toml",
    SceneError::Invalid { ref message, .. } if !message.contains("equals"),
    3,
    ["camera.target", "too far from `eye`", "overflows", "not finite"]
);
scene_case!(
    missing_camera,
    "missing_camera.toml",
    SceneError::Invalid { .. },
    1,
    ["camera", "missing"]
);
scene_case!(
    empty_file,
    "empty.toml",
    SceneError::Invalid { .. },
    1,
    ["camera", "missing"]
);
scene_case!(
    binary_garbage,
    "binary.toml",
    SceneError::Syntax { .. },
    1,
    ["not UTF-8"]
);
scene_case!(
    latin1_text,
    "latin1.toml",
    SceneError::Syntax { .. },
    4,
    ["not UTF-8"]
);
scene_case!(
    unknown_material,
    "unknown_material.toml",
    SceneError::UnknownName {
        kind: "material",
        ..
    },
    8,
    ["spheres[0].material", "no material named `gold`"]
);
scene_case!(
    unknown_texture,
    "unknown_texture.toml",
    SceneError::UnknownName {
        kind: "texture",
        ..
    },
    6,
    ["materials.wood.texture", "`oak`"]
);
scene_case!(missing_mesh, "missing_mesh.toml",
    SceneError::Mesh { ref source, .. } if matches!(**source, ObjError::Io { .. }), 6,
    ["meshes[0].file", "no_such_mesh.obj"]);
scene_case!(mesh_error_names_both_files, "bad_mesh.toml",
    SceneError::Mesh { ref source, .. } if matches!(**source, ObjError::ZeroIndex { .. }), 6,
    ["meshes[0].file", "zero_index.obj:4: f: index 0"]);
scene_case!(missing_image, "missing_image.toml",
    SceneError::Texture { ref source, .. } if matches!(**source, TextureError::Io { .. }), 7,
    ["textures.wood.file", "no_such_image.png"]);
scene_case!(corrupt_image, "corrupt_image.toml",
    SceneError::Texture { ref source, .. } if matches!(**source, TextureError::Decode { .. }),
    7, ["textures.wood.file", "corrupt.png"]);
scene_case!(
    bad_antialias,
    "bad_antialias.toml",
    SceneError::Invalid { .. },
    6,
    ["render.antialias", "none, full, adaptive"]
);
scene_case!(
    no_primitives,
    "no_primitives.toml",
    SceneError::Invalid { .. },
    1,
    ["no primitives"]
);
scene_case!(
    flat_box,
    "flat_box.toml",
    SceneError::Invalid { .. },
    7,
    ["boxes[0].max"]
);
scene_case!(
    negative_color,
    "negative_color.toml",
    SceneError::Invalid { .. },
    6,
    ["materials.ink.color", ">= 0"]
);
scene_case!(
    corner_and_center,
    "corner_and_center.toml",
    SceneError::Invalid { .. },
    11,
    ["lights[0].corner", "not both"]
);
scene_case!(
    plane_offset_and_point,
    "plane_offset_and_point.toml",
    SceneError::Invalid { .. },
    7,
    ["planes[0].offset", "not both"]
);
scene_case!(
    zero_plane_normal,
    "zero_plane_normal.toml",
    SceneError::Invalid { .. },
    6,
    ["planes[0].normal", "non-zero"]
);
scene_case!(
    negative_seed,
    "negative_seed.toml",
    SceneError::Invalid { .. },
    6,
    ["render.seed"]
);
scene_case!(
    zero_uv_scale,
    "zero_uv_scale.toml",
    SceneError::Invalid { .. },
    6,
    ["materials.m.uv_scale"]
);
scene_case!(
    unknown_light_kind,
    "unknown_light_kind.toml",
    SceneError::Invalid { .. },
    10,
    ["lights[0].kind", "`spot`"]
);
scene_case!(
    deep_nesting,
    "deep_nesting.toml",
    SceneError::Syntax { .. },
    8,
    []
);
scene_case!(
    reflection_above_one,
    "long_reflection.toml",
    SceneError::Invalid { .. },
    6,
    ["materials.m.reflection", "0 to 1"]
);

fn obj_err(name: &str) -> (ObjError, String) {
    let path = data(&format!("obj/{name}"));
    match obj::load(&path) {
        Ok(m) => panic!(
            "{} loaded ({} triangles), but it is malformed",
            path.display(),
            m.triangles.len()
        ),
        Err(e) => {
            assert!(
                raypack::is_input_error(&e),
                "{name}: not classed as bad input"
            );
            let msg = chain(&e);
            (e, msg)
        }
    }
}

macro_rules! obj_case {
    ($test:ident, $file:literal, $pat:pat $(if $guard:expr)?, $line:expr, [$($part:expr),*]) => {
        #[test]
        fn $test() {
            let (e, msg) = obj_err($file);
            assert!(matches!(e, $pat $(if $guard)?), "{}: unexpected variant: {e:?}", $file);
            if $line > 0 {
                assert_names(&msg, $file, $line, &[$($part),*]);
            } else {
                for p in [$($part),*] {
                    assert!(msg.contains(p), "`{msg}` lacks `{p}`");
                }
            }
        }
    };
}

obj_case!(
    obj_zero_index,
    "zero_index.obj",
    ObjError::ZeroIndex { line: 4, .. },
    4,
    ["f: index 0"]
);
obj_case!(
    obj_index_out_of_range,
    "out_of_range.obj",
    ObjError::IndexOutOfRange {
        index: 4,
        count: 3,
        ..
    },
    5,
    ["index 4 is out of range"]
);
obj_case!(
    obj_negative_index_out_of_range,
    "negative_out_of_range.obj",
    ObjError::IndexOutOfRange { index: -4, .. },
    4,
    ["index -4"]
);
obj_case!(
    obj_huge_index,
    "huge_index.obj",
    ObjError::Malformed { .. },
    4,
    ["is not an index"]
);
obj_case!(
    obj_nan_vertex,
    "nan_vertex.obj",
    ObjError::NonFinite { .. },
    2,
    ["v: value `nan`"]
);
obj_case!(
    obj_overflowing_vertex,
    "inf_vertex.obj",
    ObjError::NonFinite { .. },
    2,
    ["`1e39`"]
);
obj_case!(
    obj_short_vertex,
    "short_vertex.obj",
    ObjError::Malformed { .. },
    2,
    ["v: needs 3 coordinates"]
);
obj_case!(
    obj_bad_face_token,
    "bad_face_token.obj",
    ObjError::Malformed { .. },
    4,
    ["`two` is not an index"]
);
obj_case!(
    obj_too_many_slashes,
    "too_many_slashes.obj",
    ObjError::Malformed { .. },
    4,
    ["more than v/vt/vn"]
);
obj_case!(
    obj_two_vertex_face,
    "two_vertex_face.obj",
    ObjError::Malformed { .. },
    4,
    ["at least 3 vertices"]
);
obj_case!(
    obj_texcoord_out_of_range,
    "texcoord_out_of_range.obj",
    ObjError::IndexOutOfRange {
        what: "texture coordinates",
        ..
    },
    5,
    ["index 2"]
);
obj_case!(
    obj_empty,
    "empty.obj",
    ObjError::Empty { .. },
    0,
    ["empty.obj", "no faces"]
);
obj_case!(
    obj_only_vertices,
    "only_vertices.obj",
    ObjError::Empty { .. },
    0,
    ["no faces"]
);
obj_case!(
    obj_missing_mtl,
    "missing_mtl.obj",
    ObjError::MissingMtl { line: 1, .. },
    1,
    ["mtllib", "no_such.mtl"]
);
obj_case!(
    obj_unknown_usemtl,
    "unknown_usemtl.obj",
    ObjError::UnknownMaterial { .. },
    5,
    ["`chrome`"]
);
obj_case!(
    mtl_short_kd_names_the_mtl_line,
    "short_kd.obj",
    ObjError::Malformed { .. },
    0,
    ["short_kd.mtl:3: Kd: needs 3 numbers"]
);
obj_case!(
    mtl_missing_texture,
    "missing_texture.obj",
    ObjError::MissingTexture { .. },
    0,
    ["missing_texture.mtl:3: map_Kd", "no_such_wood.png"]
);
obj_case!(
    obj_mixed_vertex_colours,
    "mixed_colours.obj",
    ObjError::Malformed { .. },
    2,
    ["vertex colours"]
);
obj_case!(
    obj_zero_weight,
    "zero_weight.obj",
    ObjError::Malformed { .. },
    1,
    ["weight"]
);
obj_case!(
    obj_not_utf8,
    "not_utf8.obj",
    ObjError::Malformed { .. },
    4,
    ["not UTF-8"]
);
obj_case!(
    obj_binary_garbage,
    "binary.obj",
    ObjError::Malformed { .. },
    2,
    ["not UTF-8"]
);
obj_case!(
    obj_missing_file,
    "no_such_file.obj",
    ObjError::Io { .. },
    0,
    ["no_such_file.obj"]
);

fn texture_err(name: &str) -> (TextureError, String) {
    let path = data(&format!("texture/{name}"));
    match texture::load(&path) {
        Ok(t) => panic!(
            "{} decoded ({}x{}), but it is corrupt",
            path.display(),
            t.width,
            t.height
        ),
        Err(e) => {
            assert!(
                raypack::is_input_error(&e),
                "{name}: not classed as bad input"
            );
            let msg = chain(&e);
            assert!(msg.contains(name), "`{msg}` does not name {name}");
            (e, msg)
        }
    }
}

/// Each error of `e`'s chain leaves its cause to the next, and the chain names `file`
/// once.
fn assert_says_once(e: &(dyn Error + 'static), file: &str) {
    let mut error: &dyn Error = e;
    while let Some(cause) = error.source() {
        let (msg, cause_msg) = (error.to_string(), cause.to_string());
        assert!(
            !msg.contains(&cause_msg),
            "`{msg}` repeats its cause `{cause_msg}`"
        );
        error = cause;
    }
    let msg = chain(e);
    assert_eq!(
        msg.matches(file).count(),
        1,
        "`{msg}` names {file} more than once"
    );
}

macro_rules! texture_case {
    ($test:ident, $file:literal, $pat:pat, $want:literal) => {
        #[test]
        fn $test() {
            let (e, msg) = texture_err($file);
            assert!(matches!(e, $pat), "{}: unexpected variant: {e:?}", $file);
            assert!(msg.contains($want), "`{msg}` lacks `{}`", $want);
            assert_says_once(&e, $file);
        }
    };
}

texture_case!(
    corrupt_png,
    "corrupt.png",
    TextureError::Decode { format: "PNG", .. },
    "corrupt.png: cannot decode PNG texture: "
);
texture_case!(
    truncated_png,
    "truncated.png",
    TextureError::Decode { format: "PNG", .. },
    "truncated.png: cannot decode PNG texture: unexpected end of file"
);
texture_case!(
    empty_texture,
    "empty.png",
    TextureError::Empty { .. },
    "empty.png: texture file is empty"
);
texture_case!(
    text_named_jpg,
    "text.jpg",
    TextureError::NotAnImage { .. },
    "text.jpg: text (`this is not a jpeg`), not a PNG, JPEG or TGA image"
);
texture_case!(
    pdf_named_png,
    "document.png",
    TextureError::NotAnImage { .. },
    "document.png: a PDF document, not a PNG, JPEG or TGA image"
);
texture_case!(
    gif_named_png,
    "gif_named.png",
    TextureError::Unsupported { format: "GIF", .. },
    "gif_named.png: GIF image; textures must be PNG, JPEG or TGA"
);
texture_case!(
    missing_texture,
    "no_such_texture.png",
    TextureError::Io { .. },
    "no_such_texture.png: cannot read texture: "
);

/// Through a scene file: the scene's place, then the texture's file and fault, each once.
#[test]
fn texture_errors_in_scenes_say_each_thing_once() {
    for (scene, texture) in [
        ("corrupt_image.toml", "corrupt.png"),
        ("missing_image.toml", "no_such_image.png"),
        ("mesh_corrupt_texture.toml", "truncated.png"),
    ] {
        let (e, msg) = scene_err(scene);
        assert!(matches!(e, SceneError::Texture { .. }), "{scene}: {e:?}");
        assert_says_once(&e, scene);
        assert_says_once(&e, texture);
        assert_eq!(msg.matches(" texture:").count(), 1, "{msg}");
    }
}

/// What a hostile text must give.
#[derive(Clone, Copy)]
enum Hostile {
    /// Refused: the variant, the line, and what the message names.
    Refused(fn(&SceneError) -> bool, usize, &'static [&'static str]),
    /// Well-formed and finite: loading and refusing are both fine.
    Either,
}

/// Hostile text that is not in the corpus: none of it may panic, and what is malformed is
/// refused as bad input with its variant, line and key.
#[test]
fn hostile_scene_text_never_panics() {
    use Hostile::{Either, Refused};
    let path = data("scene/generated.toml");
    let cam = "[camera]\neye = [0, 0, -5]\ntarget = [0, 0, 0]\n";
    let invalid = |e: &SceneError| matches!(e, SceneError::Invalid { .. });
    let no_camera = Refused(invalid, 1, &["camera", "missing"]);
    let cases = [
        (String::new(), no_camera),
        (
            "\u{0}\u{1}\u{2}".to_string(),
            Refused(|e| matches!(e, SceneError::Syntax { .. }), 1, &[]),
        ),
        ("[[spheres]]\n".repeat(10_000), no_camera),
        (
            format!("{cam}[[spheres]]\ncenter = [0, 0, 0]\nradius = 1e-45\n"),
            Either,
        ),
        (
            format!("{cam}[render]\nwidth = 0x7fffffffffffffff\n"),
            Refused(invalid, 5, &["render.width", "out of range"]),
        ),
        (
            format!("{cam}[render]\nwidth = -9223372036854775808\n"),
            Refused(invalid, 5, &["render.width", "out of range"]),
        ),
        (
            format!("{cam}[render]\nwidth = 1.5\n"),
            Refused(invalid, 5, &["render.width", "expected an integer"]),
        ),
        (
            format!("{cam}[[lights]]\nkind = 5\n"),
            Refused(invalid, 5, &["lights[0].kind", "expected a string"]),
        ),
        (
            format!(
                "{cam}[textures.t]\nkind = \"checker\"\nwidth = 4096\nheight = 4096\nsquares = 0\n"
            ),
            Refused(invalid, 8, &["textures.t.squares", "out of range"]),
        ),
        (
            format!("{cam}[[meshes]]\nfile = \"\"\n"),
            Refused(invalid, 5, &["meshes[0].file", "empty file name"]),
        ),
        (
            format!("{cam}[[meshes]]\nfile = \"/\"\n"),
            Refused(
                |e| matches!(e, SceneError::Mesh { .. }),
                5,
                &["meshes[0].file", "cannot load the mesh"],
            ),
        ),
        (
            format!("{}{cam}", "# comment\n".repeat(1000)),
            Refused(invalid, 1, &["no primitives"]),
        ),
        (
            format!("{cam}x = {{a = {{b = {{c = {{d = 1}}}}}}}}\n"),
            Refused(
                |e| matches!(e, SceneError::UnknownKey { .. }),
                4,
                &["camera.x"],
            ),
        ),
        (
            format!("{cam}[[spheres]]\ncenter = [1e38, 1e38, 1e38]\nradius = 3e38\n"),
            Either,
        ),
    ];
    for (text, expect) in &cases {
        let head = &text[..text.len().min(80)];
        match (file::parse(&path, text), expect) {
            (Err(e), Refused(variant, line, parts)) => {
                assert!(variant(&e), "{head:?}: unexpected variant: {e:?}");
                assert!(raypack::is_input_error(&e), "{head:?}: not bad input");
                assert_names(&chain(&e), "generated.toml", *line, parts);
            }
            (Ok(_), Refused(..)) => panic!("{head:?} loaded, but it is malformed"),
            (Err(e), Either) => assert!(raypack::is_input_error(&e), "{head:?}: {e:?}"),
            (Ok(_), Either) => {}
        }
    }
}

/// Uniform in `0..n` by the remainder, the draw the mutation tests were written with.
fn below(rng: &mut SplitMix64, n: usize) -> usize {
    (rng.next_u64() % n as u64) as usize
}

/// `text` with a few bytes replaced, inserted or deleted; replacements favour bytes that
/// matter to the grammars (digits, signs, brackets, quotes, newlines).
fn mutate(text: &[u8], rng: &mut SplitMix64) -> Vec<u8> {
    const INTERESTING: &[u8] = b"0123456789-+.eE[]{}\"=,/ \n#nainf\x00\xff";
    let mut out = text.to_vec();
    for _ in 0..1 + below(rng, 4) {
        let at = below(rng, out.len() + 1);
        let byte = if below(rng, 4) == 0 {
            rng.next_u64() as u8
        } else {
            INTERESTING[below(rng, INTERESTING.len())]
        };
        match below(rng, 3) {
            0 if at < out.len() => out[at] = byte,
            1 if at < out.len() => {
                out.remove(at);
            }
            _ => out.insert(at, byte),
        }
    }
    out
}

#[test]
fn mutated_scene_files_never_panic() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut seeds: Vec<Vec<u8>> = ["scenes/part1.toml", "scenes/part5.toml"]
        .iter()
        .map(|p| std::fs::read(root.join(p)).unwrap())
        .collect();
    seeds.push(
        b"[camera]\neye = [0, 1, -5]\ntarget = [0, 0, 0]\nup = [0, 1, 0]\nvfov = 45\n\
          [render]\nwidth = 64\nheight = 48\nantialias = \"full\"\nantialias_n = 2\nseed = 3\n\
          [textures.c]\nkind = \"checker\"\nwidth = 8\nheight = 8\nsquares = 2\n\
          [textures.b]\nkind = \"bricks\"\nwidth = 16\nheight = 16\nrows = 4\n\
          [textures.m]\nkind = \"marble\"\nwidth = 16\nheight = 8\nscale = 2\n\
          [materials.a]\ntexture = \"c\"\nuv_scale = [0.5, 2]\nior = 1.3\nrefraction = 0.5\n\
          [[boxes]]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\nmaterial = \"a\"\n\
          [[lights]]\nkind = \"area\"\ncorner = [0, 4, 0]\nedge_u = [1, 0, 0]\nedge_v = [0, 0, 1]\n"
            .to_vec(),
    );
    let path = root.join("scenes/mutated.toml");
    let mut rng = SplitMix64::new(2024);
    let (mut ok, mut rejected) = (0, 0);
    for i in 0..3000 {
        let text = mutate(&seeds[i % seeds.len()], &mut rng);
        let Ok(text) = std::str::from_utf8(&text) else {
            continue;
        };
        match file::parse(&path, text) {
            Ok(_) => ok += 1,
            Err(e) => {
                assert!(raypack::is_input_error(&e));
                assert!(e.to_string().contains("mutated.toml:"), "{e}");
                rejected += 1;
            }
        }
    }
    assert!(ok > 0 && rejected > 0, "ok {ok}, rejected {rejected}");
}

#[test]
fn mutated_obj_files_never_panic() {
    let seed = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n\
                 o a\nusemtl red\nf 1/1/1 2/2/1 3/1/1 4/2/1\ng b\nf -1 -2 -3\nl 1 2 3\n";
    let dir = std::env::temp_dir().join(format!("raypack-mutated-obj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
    let path = dir.join("m.obj");
    let mut rng = SplitMix64::new(7);
    let (mut ok, mut rejected) = (0, 0);
    for _ in 0..1500 {
        std::fs::write(&path, mutate(seed, &mut rng)).unwrap();
        match obj::load(&path) {
            Ok(m) => {
                assert_eq!(m.tri_material.len(), m.triangles.len());
                assert_eq!(m.normals.len(), m.positions.len());
                assert!(
                    m.triangles
                        .iter()
                        .flatten()
                        .all(|&i| (i as usize) < m.positions.len())
                );
                ok += 1;
            }
            Err(e) => {
                assert!(!matches!(e, ObjError::Inconsistent { .. }), "{e}");
                assert!(
                    e.to_string().contains("m.obj") || e.to_string().contains("m.mtl"),
                    "{e}"
                );
                rejected += 1;
            }
        }
    }
    assert!(ok > 0 && rejected > 0, "ok {ok}, rejected {rejected}");
}

/// The CLI turns every kind of bad input into exit code 2 and one message naming the
/// file, line and key.
#[test]
fn cli_exits_2_naming_the_place() {
    let out_png = std::env::temp_dir().join(format!("raypack-bad-{}.png", std::process::id()));
    for (rel, want) in [
        (
            "scene/negative_radius.toml",
            "negative_radius.toml:7: spheres[0].radius",
        ),
        ("scene/bad_mesh.toml", "zero_index.obj:4: f: index 0"),
        (
            "scene/corrupt_image.toml",
            "/texture/corrupt.png: cannot decode PNG texture: ",
        ),
        (
            "scene/no_such_scene.toml",
            "no_such_scene.toml: cannot read scene file",
        ),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_raypack"))
            .arg("render")
            .arg(data(rel))
            .arg("-o")
            .arg(&out_png)
            .output()
            .expect("raypack runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{rel}: {stderr}");
        assert!(stderr.contains(want), "{rel}: `{stderr}` lacks `{want}`");
        assert!(!stderr.contains("panicked"), "{rel}: {stderr}");
        assert!(!out_png.exists(), "{rel}: an image was written");
    }
}

scene_case!(
    texture_budget,
    "too_many_texels.toml",
    SceneError::Invalid { .. },
    25,
    ["textures.t4", "texels in all"]
);
scene_case!(
    vfov_180,
    "vfov_180.toml",
    SceneError::Invalid { .. },
    4,
    ["camera.vfov", "< 180 degrees"]
);
scene_case!(
    up_zero,
    "up_zero.toml",
    SceneError::Invalid { .. },
    4,
    ["camera.up", "is zero"]
);
scene_case!(
    antialias_n_too_large,
    "antialias_n_too_large.toml",
    SceneError::Invalid { .. },
    7,
    ["render.antialias_n", "1 to 16"]
);
scene_case!(texture_is_a_folder, "texture_is_folder.toml",
    SceneError::Texture { ref source, .. }
        if matches!(**source, TextureError::Io { .. }),
    7, ["textures.wood.file", "texture"]);
scene_case!(mtl_texture_corrupt_names_the_texture, "mesh_corrupt_texture.toml",
    SceneError::Texture { ref source, .. } if matches!(**source, TextureError::Decode { .. }),
    6, ["meshes[0].file: ", "truncated.png: cannot decode PNG texture"]);

/// The CLI's whole message for `args`: exit code 2, one line `raypack: ` followed by the
/// library's error chain, no panic, no image.
fn cli_rejects(args: &[&std::ffi::OsStr], want: &str) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_raypack"))
        .args(args)
        .output()
        .expect("raypack runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert_eq!(stderr, format!("raypack: {want}\n"), "{args:?}");
}

/// Every scene file of the corpus through `raypack render` and every OBJ file through
/// `raypack info`: exit code 2 and exactly the library's message (which the cases above
/// pin down to file, line and key).
#[test]
fn cli_exits_2_with_the_library_message_for_the_whole_corpus() {
    let out_png = std::env::temp_dir().join(format!("raypack-corpus-{}.png", std::process::id()));
    let mut count = 0;
    for kind in ["scene", "obj"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(data(kind))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml" || e == "obj"))
            .filter(|p| (kind == "scene") == p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        for path in files {
            let (want, args) = if kind == "scene" {
                let e = file::load(&path).expect_err("a malformed scene loads");
                let args = vec![
                    "render".as_ref(),
                    path.as_os_str(),
                    "-o".as_ref(),
                    out_png.as_os_str(),
                ];
                (chain(&e), args)
            } else {
                let e = obj::load(&path).expect_err("a malformed mesh loads");
                (chain(&e), vec!["info".as_ref(), path.as_os_str()])
            };
            cli_rejects(&args, &want);
            assert!(
                !out_png.exists(),
                "{}: an image was written",
                path.display()
            );
            count += 1;
        }
    }
    assert!(count > 60, "only {count} corpus files");
}

/// Every file of tests/data/bad has a case in this file that pins its error down, or is
/// used by another corpus file (an MTL library, a texture of a mesh).
#[test]
fn every_corpus_file_has_a_case() {
    let kinds = ["scene", "obj", "texture"];
    let mut files = Vec::new();
    for kind in kinds {
        for e in std::fs::read_dir(data(kind)).unwrap() {
            let path = e.unwrap().path();
            let text = String::from_utf8_lossy(&std::fs::read(&path).unwrap()).into_owned();
            files.push((
                kind,
                path.file_name().unwrap().to_str().unwrap().to_string(),
                text,
            ));
        }
    }
    let source = include_str!("bad_input.rs");
    for (kind, name, _) in &files {
        let in_case = source.contains(&format!("\"{name}\""))
            || source.contains(&format!("{name}:"))
            || source.contains(&format!("/{name}\""));
        let used = files
            .iter()
            .any(|(_, other, text)| other != name && text.contains(name.as_str()));
        assert!(in_case || used, "tests/data/bad/{kind}/{name} has no case");
    }
}
scene_case!(
    rotate_both_forms,
    "rotate_both_forms.toml",
    SceneError::Invalid { .. },
    7,
    ["meshes[0].rotate", "not both"]
);
scene_case!(
    rotate_zero_axis,
    "rotate_zero_axis.toml",
    SceneError::Invalid { .. },
    7,
    ["meshes[0].rotate_axis", "the axis is zero"]
);
scene_case!(
    rotate_wrong_length,
    "rotate_wrong_length.toml",
    SceneError::Invalid { .. },
    7,
    ["meshes[0].rotate", "array of 3 numbers"]
);
scene_case!(
    rotate_nan_angle,
    "rotate_nan_angle.toml",
    SceneError::Invalid { .. },
    8,
    ["meshes[0].rotate_angle", "not a finite number"]
);
scene_case!(
    rotate_angle_without_axis,
    "rotate_angle_without_axis.toml",
    SceneError::Invalid { .. },
    7,
    [
        "meshes[0].rotate_axis",
        "`rotate_angle` needs `rotate_axis`"
    ]
);
scene_case!(
    rotate_axis_without_angle,
    "rotate_axis_without_angle.toml",
    SceneError::Invalid { .. },
    5,
    [
        "meshes[0].rotate_angle",
        "`rotate_axis` needs `rotate_angle`"
    ]
);
scene_case!(
    deep_dotted_key_names_its_line,
    "deep_dotted_key.toml",
    SceneError::Syntax { .. },
    8,
    ["recursion limit"]
);
