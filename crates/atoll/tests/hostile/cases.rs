//! The generator: hundreds of hostile and careless inputs made from the
//! valid [`templates`](super::templates) by systematic mutation, each a
//! [`Case`]: the files of its folder, the command line, and what must come
//! of it.

use super::templates as t;

/// One file of a case's folder.
pub enum Entry {
    Bytes(Vec<u8>),
    /// A symbolic link to this target.
    Link(String),
    /// A named pipe (reading one would block for ever).
    Fifo,
    /// A sparse file of this many bytes (a huge file that takes no disk).
    Sparse(u64),
    Dir,
}

/// An input and what the binary must make of it. Whatever the case, the
/// runner also requires: no panic text, no signal, no timeout, a `out.png`
/// already there byte-identical unless the run succeeded, and no file left
/// in the folder but those the case made and the outputs it allows.
pub struct Case {
    /// The class of the issue the case belongs to (for the counts).
    pub class: &'static str,
    pub name: String,
    pub files: Vec<(String, Entry)>,
    /// The arguments of `atoll`, run in the case's folder.
    pub args: Vec<String>,
    /// Exit codes allowed.
    pub codes: &'static [i32],
    /// Texts stderr must contain, whatever the exit code.
    pub always: Vec<String>,
    /// Texts stderr must contain when the exit code is not 0.
    pub on_failure: Vec<String>,
    /// On failure stderr must contain `FILE:LINE:` for this file (any
    /// line): the location of a syntax error.
    pub line_in: Option<String>,
    /// Files the command may create besides its image.
    pub creates: Vec<String>,
}

/// Exit codes (README, "Exit codes").
pub const OK: &[i32] = &[0];
pub const BAD_INPUT: &[i32] = &[2];
pub const TOO_BIG: &[i32] = &[1];
pub const OK_OR_BAD: &[i32] = &[0, 2];
pub const REFUSED: &[i32] = &[1, 2];

/// The command line of a small render of `scene` into `out.png`.
pub fn render_args(scene: &str) -> Vec<String> {
    args(&["render", scene, "-o", "out.png", "--res", "16x16", "--spp", "1", "-q", "--device", "cpu"])
}

fn args(a: &[&str]) -> Vec<String> {
    a.iter().map(|s| s.to_string()).collect()
}

impl Case {
    /// A render of `scene`, one of `files`, that must succeed.
    fn render(
        class: &'static str,
        name: impl Into<String>,
        scene: &str,
        files: Vec<(String, Entry)>,
    ) -> Case {
        Case {
            class,
            name: name.into(),
            files,
            args: render_args(scene),
            codes: OK,
            always: Vec::new(),
            on_failure: Vec::new(),
            line_in: None,
            creates: Vec::new(),
        }
    }

    /// A run of `atoll` with `args` in a folder of `files`.
    fn cli(class: &'static str, name: impl Into<String>, a: &[&str], files: Vec<(String, Entry)>) -> Case {
        Case { args: args(a), ..Case::render(class, name, "", files) }
    }

    fn codes(mut self, codes: &'static [i32]) -> Case {
        self.codes = codes;
        self
    }

    /// The same command with `extra` arguments after the others.
    fn and_args(mut self, extra: &[&str]) -> Case {
        self.args.extend(args(extra));
        self
    }

    /// Fails with exit code 2, saying `text`.
    fn bad(self, text: impl Into<String>) -> Case {
        self.codes(BAD_INPUT).says(text)
    }

    fn says(mut self, text: impl Into<String>) -> Case {
        self.always.push(text.into());
        self
    }

    fn says_on_failure(mut self, text: impl Into<String>) -> Case {
        self.on_failure.push(text.into());
        self
    }

    fn line_in(mut self, file: &str) -> Case {
        self.line_in = Some(file.into());
        self
    }

    /// Render arguments replaced (the scene stays `scene`).
    fn with_args(mut self, a: &[&str]) -> Case {
        self.args = args(a);
        self
    }
}

fn file(name: &str, bytes: impl Into<Vec<u8>>) -> (String, Entry) {
    (name.to_string(), Entry::Bytes(bytes.into()))
}

/// `scene.pbrt` with `text`.
fn scene(text: impl Into<Vec<u8>>) -> Vec<(String, Entry)> {
    vec![file("scene.pbrt", text)]
}

/// `scene.pbrt:LINE:` for a message.
fn at(line: usize) -> String {
    format!("scene.pbrt:{line}:")
}

/// Every case, in a stable order.
pub fn all(scratch: &std::path::Path) -> Vec<Case> {
    let mut cases = Vec::new();
    cases.extend(templates(scratch));
    cases.extend(pbrt_numbers());
    cases.extend(pbrt_meaning());
    cases.extend(pbrt_syntax());
    cases.extend(hostile_paths());
    cases.extend(ply());
    cases.extend(off());
    cases.extend(obj());
    cases.extend(gltf());
    cases.extend(images(scratch));
    cases.extend(gzip());
    cases.extend(sizes());
    cases.extend(cli(scratch));
    cases
}

/// Every template as it is: all must render.
fn templates(scratch: &std::path::Path) -> Vec<Case> {
    let c = "template";
    let png = || file("tex.png", t::png(4, 4));
    vec![
        Case::render(c, "pbrt", "scene.pbrt", scene(t::pbrt())),
        Case::render(
            c,
            "pbrt.gz",
            "scene.pbrt.gz",
            vec![file("scene.pbrt.gz", t::gzip(t::pbrt().as_bytes()))],
        ),
        Case::render(c, "ply-ascii", "model.ply", vec![file("model.ply", t::PLY_ASCII)]),
        Case::render(c, "ply-le", "model.ply", vec![file("model.ply", t::ply_binary(false))]),
        Case::render(c, "ply-be", "model.ply", vec![file("model.ply", t::ply_binary(true))]),
        Case::render(c, "ply.gz", "model.ply.gz", vec![file("model.ply.gz", t::gzip(&t::ply_binary(false)))]),
        Case::render(c, "off", "model.off", vec![file("model.off", t::OFF)]),
        Case::render(
            c,
            "obj",
            "model.obj",
            vec![file("model.obj", t::OBJ), file("model.mtl", t::MTL), png()],
        ),
        Case::render(
            c,
            "gltf",
            "model.gltf",
            vec![file("model.gltf", t::gltf()), file("model.bin", t::gltf_bin()), png()],
        ),
        Case::render(c, "gltf-data-uri", "model.gltf", vec![file("model.gltf", t::gltf_data_uri()), png()]),
        Case::render(c, "glb", "model.glb", vec![file("model.glb", t::glb()), png()]),
        Case::render(
            c,
            "plymesh",
            "scene.pbrt",
            vec![
                file("scene.pbrt", t::pbrt_with("Shape \"plymesh\" \"string filename\" \"model.ply\"")),
                file("model.ply", t::ply_binary(false)),
            ],
        ),
        Case::render(
            c,
            "include",
            "scene.pbrt",
            vec![
                file("scene.pbrt", t::pbrt_with("Include \"more.pbrt\"")),
                file("more.pbrt", "Shape \"sphere\"\n"),
            ],
        ),
        Case::render(c, "imagemap-png", "scene.pbrt", image_scene("tex.png", t::png(4, 4))),
        Case::render(c, "imagemap-exr", "scene.pbrt", image_scene("tex.exr", t::exr(scratch))),
        Case::render(c, "envmap-exr", "scene.pbrt", envmap_scene("env.exr", t::exr(scratch))),
    ]
}

/// A scene whose material reads the image `name`.
fn image_scene(name: &str, bytes: Vec<u8>) -> Vec<(String, Entry)> {
    let text = t::pbrt_with(&format!(
        "Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"{name}\" Material \"diffuse\" \"texture reflectance\" \"t\" Shape \"sphere\""
    ));
    vec![file("scene.pbrt", text), file(name, bytes)]
}

/// A scene lit by the environment map `name`.
fn envmap_scene(name: &str, bytes: Vec<u8>) -> Vec<(String, Entry)> {
    let text = t::pbrt_with(&format!("LightSource \"infinite\" \"string filename\" \"{name}\""));
    vec![file("scene.pbrt", text), file(name, bytes)]
}

/// The numbers of the template's lines: (line index, byte range).
fn numbers() -> Vec<(usize, std::ops::Range<usize>)> {
    let mut found = Vec::new();
    for (i, line) in t::PBRT.iter().enumerate() {
        if line.starts_with('#') {
            continue;
        }
        let mut in_string = false;
        let mut start = None;
        for (j, ch) in line.char_indices().chain([(line.len(), ' ')]) {
            if ch == '"' {
                in_string = !in_string;
            }
            let numeric = !in_string && (ch.is_ascii_digit() || ch == '.' || ch == '-');
            match (numeric, start) {
                (true, None) => start = Some(j),
                (false, Some(s)) => {
                    found.push((i, s..j));
                    start = None;
                }
                _ => {}
            }
        }
    }
    found
}

/// Every number of the template replaced by numbers past f32's range (refused
/// at their line), by the largest ones (a scene of such sizes renders or is
/// refused at its line, but nothing overflows into a crash), by 0 and by -1.
fn pbrt_numbers() -> Vec<Case> {
    let mut cases = Vec::new();
    for (i, range) in numbers() {
        for value in ["1e400", "-1e39", "3e38", "-3e38", "0", "-1"] {
            let mut lines: Vec<String> = t::PBRT.iter().map(|s| s.to_string()).collect();
            let original = lines[i][range.clone()].to_string();
            lines[i].replace_range(range.clone(), value);
            let text = t::join(lines.iter().map(String::as_str));
            let name = format!("line {}: {original} -> {value} at col {}", i + 1, range.start + 1);
            let case = Case::render("float overflow", name, "scene.pbrt", scene(text));
            cases.push(match value {
                "1e400" | "-1e39" => case.bad(at(i + 1)).says("out of range"),
                _ => case.codes(OK_OR_BAD).says_on_failure(at(i + 1)),
            });
        }
    }
    cases
}

/// Physically meaningless parameters and sizes that wrap: refused at their line.
fn pbrt_meaning() -> Vec<Case> {
    let c = "meaningless values";
    let mut cases = Vec::new();
    let template = |i: usize, line: &str| {
        let mut lines: Vec<&str> = t::PBRT.to_vec();
        lines[i] = line;
        t::join(lines)
    };
    for fov in ["0", "180", "-10", "200"] {
        let text = template(2, &format!("Camera \"perspective\" \"float fov\" [ {fov} ]"));
        cases.push(Case::render(c, format!("fov {fov}"), "scene.pbrt", scene(text)).bad(at(3)));
    }
    for rgb in ["-1 1 1", "1 -1 1", "1 1 -0.001"] {
        let text = template(10, &format!("  AreaLightSource \"diffuse\" \"rgb L\" [ {rgb} ]"));
        cases.push(Case::render(c, format!("area light L {rgb}"), "scene.pbrt", scene(text)).bad(at(11)));
        let text = template(7, &format!("LightSource \"point\" \"rgb I\" [ {rgb} ]"));
        cases.push(Case::render(c, format!("point light I {rgb}"), "scene.pbrt", scene(text)).bad(at(8)));
    }
    for k in ["0", "-1", "-6500"] {
        let text = template(8, &format!("LightSource \"infinite\" \"blackbody L\" [ {k} ]"));
        cases.push(Case::render(c, format!("blackbody {k}"), "scene.pbrt", scene(text)).bad(at(9)));
    }
    for scale in ["-1", "1e38"] {
        let text =
            template(8, &format!("LightSource \"infinite\" \"rgb L\" [ 1 1 1 ] \"float scale\" [ {scale} ]"));
        cases.push(
            Case::render(c, format!("light scale {scale}"), "scene.pbrt", scene(text))
                .codes(OK_OR_BAD)
                .says_on_failure(at(9)),
        );
    }
    // Sizes from the scene itself (no --res, --spp to override them).
    let own = |name: String, text: String| {
        Case::render(c, name, "scene.pbrt", scene(text)).with_args(&[
            "render",
            "scene.pbrt",
            "-o",
            "out.png",
            "-q",
            "--device",
            "cpu",
        ])
    };
    for (x, y) in [("4294967296", "16"), ("4294967297", "1"), ("65536", "65536"), ("0", "16"), ("-16", "16")]
    {
        let text = template(
            3,
            &format!("Film \"rgb\" \"integer xresolution\" [ {x} ] \"integer yresolution\" [ {y} ]"),
        );
        cases.push(own(format!("film resolution {x}x{y}"), text).bad(at(4)));
    }
    for spp in ["0", "-1", "4294967296", "4294967297"] {
        let text = template(4, &format!("Sampler \"independent\" \"integer pixelsamples\" [ {spp} ]"));
        cases.push(own(format!("pixelsamples {spp}"), text).bad(at(5)));
    }
    for depth in ["-1", "4294967296"] {
        let text = template(5, &format!("Integrator \"volpath\" \"integer maxdepth\" [ {depth} ]"));
        cases.push(Case::render(c, format!("maxdepth {depth}"), "scene.pbrt", scene(text)).bad(at(6)));
    }
    for radius in ["0", "-1"] {
        let text = template(17, &format!("Shape \"sphere\" \"float radius\" [ {radius} ]"));
        cases.push(
            Case::render(c, format!("sphere radius {radius}"), "scene.pbrt", scene(text))
                .codes(OK_OR_BAD)
                .says_on_failure(at(18)),
        );
    }
    for index in ["3", "-1", "4294967296", "1.5"] {
        let text = template(11, &format!("  Shape \"trianglemesh\" \"point3 P\" [ 0 0 0 1 0 0 0 1 0 ] \"integer indices\" [ 0 1 {index} ]"));
        cases.push(Case::render(c, format!("triangle index {index}"), "scene.pbrt", scene(text)).bad(at(12)));
    }
    cases
}

/// Truncations at many byte offsets and token-level edits of every line:
/// a scene that no longer parses is refused at a line of its file.
fn pbrt_syntax() -> Vec<Case> {
    let c = "syntax";
    let mut cases = Vec::new();
    let text = t::pbrt();
    for cut in (1..text.len()).step_by(11) {
        let case = Case::render(c, format!("truncated at byte {cut}"), "scene.pbrt", scene(&text[..cut]));
        cases.push(case.codes(OK_OR_BAD).line_in("scene.pbrt"));
    }
    for (i, line) in t::PBRT.iter().enumerate().skip(1) {
        let mut edits: Vec<(&str, String)> = vec![
            ("line doubled", format!("{line}\n{line}")),
            ("directive misspelt", format!("X{}", line.trim_start())),
            ("quote dropped", line.replacen('"', "", 1)),
            ("first word dropped", line.trim_start().split_once(' ').map_or("", |s| s.1).to_string()),
        ];
        if let Some(k) = line.rfind(']') {
            edits.push(("closing bracket dropped", format!("{}{}", &line[..k], &line[k + 1..])));
        }
        for ty in ["float", "rgb", "integer", "point3"] {
            if line.contains(&format!("\"{ty} ")) {
                edits.push(("type changed", line.replacen(&format!("\"{ty} "), "\"string ", 1)));
                break;
            }
        }
        if let Some(k) = line.find('[') {
            edits.push(("values quoted", format!("{}[ \"a\" {}", &line[..k], &line[k + 1..])));
        }
        for (what, edited) in edits {
            let mut lines: Vec<String> = t::PBRT.iter().map(|s| s.to_string()).collect();
            lines[i] = edited;
            let text = t::join(lines.iter().map(String::as_str));
            let case = Case::render(c, format!("line {}: {what}", i + 1), "scene.pbrt", scene(text));
            cases.push(case.codes(OK_OR_BAD).line_in("scene.pbrt"));
        }
    }
    let odd: Vec<(&str, Vec<u8>)> = vec![
        ("NUL bytes", t::pbrt().replace("WorldBegin", "World\0Begin").into_bytes()),
        ("not UTF-8 in a string", t::pbrt().replace("film.png", "f\u{fffd}.png").replace('\u{fffd}', "\u{1}").into_bytes().into_iter().map(|b| if b == 1 { 0xff } else { b }).collect()),
        ("not UTF-8 as a word", [t::pbrt().as_bytes(), b"\xff\xfe\n"].concat()),
        ("unterminated string", [t::pbrt().as_bytes(), b"Shape \"sphere"].concat()),
        ("a million-digit number", format!("{}Shape \"sphere\" \"float radius\" [ {} ]\n", t::pbrt(), "9".repeat(1 << 20)).into_bytes()),
        ("a million-character word", format!("{}{}\n", t::pbrt(), "A".repeat(1 << 20)).into_bytes()),
        ("100000 AttributeBegin", format!("{}{}", t::pbrt(), "AttributeBegin\n".repeat(100_000)).into_bytes()),
        ("100000 AttributeEnd", format!("{}{}", t::pbrt(), "AttributeEnd\n".repeat(100_000)).into_bytes()),
        ("100000 open brackets", format!("{}Shape \"sphere\" \"float radius\" {}\n", t::pbrt(), "[".repeat(100_000)).into_bytes()),
        ("WorldBegin twice", format!("{}WorldBegin\n", t::pbrt()).into_bytes()),
        ("undefined instance", format!("{}ObjectInstance \"nothing\"\n", t::pbrt()).into_bytes()),
        ("unfinished object", format!("{}ObjectBegin \"o\"\nShape \"sphere\"\n", t::pbrt()).into_bytes()),
        ("instance of itself", format!("{}ObjectBegin \"o\"\nObjectInstance \"o\"\nObjectEnd\nObjectInstance \"o\"\n", t::pbrt()).into_bytes()),
        ("unknown named material", format!("{}NamedMaterial \"gold\"\n", t::pbrt()).into_bytes()),
        ("texture of itself", format!("{}Texture \"a\" \"spectrum\" \"scale\" \"texture tex\" \"a\"\nMaterial \"diffuse\" \"texture reflectance\" \"a\"\nShape \"sphere\"\n", t::pbrt()).into_bytes()),
        ("empty file", Vec::new()),
        ("only a comment", b"# nothing".to_vec()),
        ("singular transform", t::pbrt().replace("WorldBegin", "WorldBegin\nScale 0 0 0").into_bytes()),
        ("degenerate LookAt", t::pbrt().replace("LookAt 0 0 5  0 0 0  0 1 0", "LookAt 0 0 0  0 0 0  0 1 0").into_bytes()),
        ("a 3 GB ConcatTransform", t::pbrt().replace("WorldBegin", "WorldBegin\nConcatTransform [ 3e38 0 0 0 0 3e38 0 0 0 0 3e38 0 0 0 0 1 ]").into_bytes()),
    ];
    for (what, bytes) in odd {
        let case = Case::render(c, what, "scene.pbrt", scene(bytes));
        cases.push(case.codes(OK_OR_BAD).line_in("scene.pbrt"));
    }
    // Include cycles, and chains deeper than any scene needs.
    let mut files = vec![file("scene.pbrt", t::pbrt_with("Include \"a.pbrt\""))];
    files.push(file("a.pbrt", "Include \"b.pbrt\"\n"));
    files.push(file("b.pbrt", "Include \"a.pbrt\"\n"));
    cases.push(Case::render(c, "include cycle", "scene.pbrt", files).bad("b.pbrt:1:"));
    cases.push(
        Case::render(c, "include itself", "scene.pbrt", scene(t::pbrt_with("Include \"scene.pbrt\"")))
            .bad(at(8)),
    );
    let mut files = vec![file("scene.pbrt", t::pbrt_with("Include \"i0.pbrt\""))];
    for i in 0..300 {
        files.push(file(&format!("i{i}.pbrt"), format!("Include \"i{}.pbrt\"\n", i + 1)));
    }
    files.push(file("i300.pbrt", "Shape \"sphere\"\n"));
    cases.push(
        Case::render(c, "include chain of 300", "scene.pbrt", files)
            .codes(OK_OR_BAD)
            .says_on_failure("scene.pbrt"),
    );
    cases
}

/// The special files a hostile scene may name: (label, the name in the
/// scene, what lies in the folder, codes where a missing file is an error,
/// and whether it is out of reach (too big to read) rather than bad input).
struct Hostile {
    label: &'static str,
    name: &'static str,
    entry: Option<Entry>,
    too_big: bool,
}

fn hostile() -> Vec<Hostile> {
    let h = |label, name, entry, too_big| Hostile { label, name, entry, too_big };
    vec![
        h("climbs out", "../../../etc/passwd", None, false),
        h("absolute", "/etc/passwd", None, false),
        h("file URI", "file:///etc/passwd", None, false),
        h("device", "/dev/zero", None, false),
        h("climbs out below", "sub/../../x.exr", None, false),
        h("symlink to /dev/zero", "x.exr", Some(Entry::Link("/dev/zero".into())), false),
        h("symlink to /dev/urandom", "x.exr", Some(Entry::Link("/dev/urandom".into())), false),
        h("symlink loop", "x.exr", Some(Entry::Link("x.exr".into())), false),
        h("named pipe", "x.exr", Some(Entry::Fifo), false),
        h("folder", "x.exr", Some(Entry::Dir), false),
        h("missing", "x.exr", None, false),
        h("empty", "x.exr", Some(Entry::Bytes(Vec::new())), false),
        h("sparse 63 GiB", "x.exr", Some(Entry::Sparse(63 << 30)), true),
        h("sparse 65 GiB", "x.exr", Some(Entry::Sparse(65 << 30)), false),
    ]
}

/// Each hostile name where each format names a file: refused (the folder's
/// other files untouched), naming the file; where the format treats an
/// unreadable file as a warning (textures, material libraries), a warning
/// that names it.
fn hostile_paths() -> Vec<Case> {
    let c = "hostile paths";
    let mut cases = Vec::new();
    for h in hostile() {
        let files = |main: (String, Entry), more: Vec<(String, Entry)>| {
            let mut f = vec![main];
            f.extend(more);
            if let Some(entry) = h.entry.as_ref() {
                f.push((h.name.to_string(), clone_entry(entry)));
            }
            f
        };
        let error = |case: Case| {
            let case = case.says(h.name);
            if h.too_big {
                case.codes(REFUSED)
            } else {
                case.codes(BAD_INPUT)
            }
        };
        // Scene statements naming a file: errors at their line.
        for (what, statement) in [
            ("Include", format!("Include \"{}\"", h.name)),
            ("Import", format!("Import \"{}\"", h.name)),
            ("plymesh", format!("Shape \"plymesh\" \"string filename\" \"{}\"", h.name)),
        ] {
            let case = Case::render(
                c,
                format!("{what} {}", h.label),
                "scene.pbrt",
                files(file("scene.pbrt", t::pbrt_with(&statement)), vec![]),
            );
            if h.label == "empty" && what != "plymesh" {
                // An empty scene file is a valid one.
                cases.push(case);
            } else {
                cases.push(error(case).says(at(t::STATEMENT_LINE)));
            }
        }
        // Images (textures, environment maps): errors at their line, or
        // with --allow-missing a warning there, the render going on.
        for (what, statement) in [
            ("imagemap", format!(
                "Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"{}\" Material \"diffuse\" \"texture reflectance\" \"t\" Shape \"sphere\"",
                h.name
            )),
            ("envmap", format!("LightSource \"infinite\" \"string filename\" \"{}\"", h.name)),
        ] {
            let case = Case::render(
                c,
                format!("{what} {}", h.label),
                "scene.pbrt",
                files(file("scene.pbrt", t::pbrt_with(&statement)), vec![]),
            );
            cases.push(error(case).says(at(t::STATEMENT_LINE)));
            let case = Case::render(
                c,
                format!("{what} {} allowed missing", h.label),
                "scene.pbrt",
                files(file("scene.pbrt", t::pbrt_with(&statement)), vec![]),
            );
            cases.push(case.and_args(&["--allow-missing"]).says(at(t::STATEMENT_LINE)).says(h.name));
        }
        // OBJ material libraries and their maps: warnings.
        let obj = t::OBJ.replace("model.mtl", h.name);
        let case = Case::render(
            c,
            format!("mtllib {}", h.label),
            "model.obj",
            files(file("model.obj", obj), vec![]),
        );
        cases.push(if h.label == "empty" { case } else { case.says("model.obj").says(h.name) });
        let mtl = t::MTL.replace("tex.png", h.name);
        let case = Case::render(
            c,
            format!("map_Kd {}", h.label),
            "model.obj",
            files(file("model.obj", t::OBJ), vec![file("model.mtl", mtl)]),
        );
        cases.push(case.says(h.name));
        // glTF buffers are errors, images warnings.
        let gltf = t::GLTF.replace("BUFFER_URI", h.name);
        let case = Case::render(
            c,
            format!("glTF buffer {}", h.label),
            "model.gltf",
            files(file("model.gltf", gltf), vec![file("tex.png", t::png(4, 4))]),
        );
        cases.push(error(case).says("model.gltf"));
        let gltf = t::gltf().replace("tex.png", h.name);
        let case = Case::render(
            c,
            format!("glTF image {}", h.label),
            "model.gltf",
            files(file("model.gltf", gltf), vec![file("model.bin", t::gltf_bin())]),
        );
        cases.push(case.says("model.gltf").says(h.name));
    }
    // The scene file itself, of each format, as a special file.
    for ext in ["pbrt", "ply", "off", "obj", "gltf", "glb", "pbrt.gz"] {
        let name = format!("scene.{ext}");
        for (label, entry, too_big) in [
            ("symlink to /dev/zero", Entry::Link("/dev/zero".into()), false),
            ("named pipe", Entry::Fifo, false),
            ("folder", Entry::Dir, false),
            ("sparse 63 GiB", Entry::Sparse(63 << 30), true),
            ("sparse 65 GiB", Entry::Sparse(65 << 30), false),
            ("empty", Entry::Bytes(Vec::new()), false),
        ] {
            let case = Case::render(c, format!("scene {name} {label}"), &name, vec![(name.clone(), entry)]);
            cases.push(case.codes(if too_big { REFUSED } else { BAD_INPUT }).says(name.as_str()));
        }
        let case = Case::render(c, format!("scene {name} missing"), &name, vec![]);
        cases.push(case.bad(name.as_str()));
    }
    // glTF URIs whose percent escapes are no text.
    for uri in ["model%FF.bin", "model%C3%28.bin", "model%.bin", "model%zz.bin", "%2e%2e/%2e%2e/etc/passwd"] {
        let gltf = t::GLTF.replace("BUFFER_URI", uri);
        let case = Case::render(
            c,
            format!("glTF buffer URI {uri}"),
            "model.gltf",
            vec![file("model.gltf", gltf), file("model.bin", t::gltf_bin())],
        );
        cases.push(case.bad("model.gltf"));
        let gltf = t::gltf().replace("tex.png", uri);
        let case = Case::render(
            c,
            format!("glTF image URI {uri}"),
            "model.gltf",
            vec![file("model.gltf", gltf), file("model.bin", t::gltf_bin())],
        );
        cases.push(case.says("model.gltf"));
    }
    cases
}

fn clone_entry(e: &Entry) -> Entry {
    match e {
        Entry::Bytes(b) => Entry::Bytes(b.clone()),
        Entry::Link(l) => Entry::Link(l.clone()),
        Entry::Fifo => Entry::Fifo,
        Entry::Sparse(n) => Entry::Sparse(*n),
        Entry::Dir => Entry::Dir,
    }
}

/// PLY headers that lie, bodies that end early or hold what no mesh can.
fn ply() -> Vec<Case> {
    let c = "PLY";
    let mut cases = Vec::new();
    // Rendered on its own and through a scene's plymesh: the file is named either way.
    let both = |cases: &mut Vec<Case>, name: String, bytes: Vec<u8>, codes: &'static [i32]| {
        let case = Case::render(c, name.clone(), "model.ply", vec![file("model.ply", bytes.clone())]);
        cases.push(case.codes(codes).says_on_failure("model.ply"));
        let statement = "Shape \"plymesh\" \"string filename\" \"model.ply\"";
        let case = Case::render(
            c,
            format!("{name} (plymesh)"),
            "scene.pbrt",
            vec![file("scene.pbrt", t::pbrt_with(statement)), file("model.ply", bytes)],
        );
        cases.push(case.codes(codes).says_on_failure("model.ply").says_on_failure(at(t::STATEMENT_LINE)));
    };
    for count in [
        "5",
        "4000000000",
        "1000000000000000000",
        "18446744073709551615",
        "18446744073709551616",
        "-1",
        "0x10",
        "0",
    ] {
        let header = t::PLY_ASCII.replace("element vertex 4", &format!("element vertex {count}"));
        both(&mut cases, format!("ascii vertex count {count}"), header.into_bytes(), BAD_INPUT);
        // No faces: an empty shape in a scene, no model on its own.
        let codes = if count == "0" { OK_OR_BAD } else { BAD_INPUT };
        let header = t::PLY_ASCII.replace("element face 2", &format!("element face {count}"));
        both(&mut cases, format!("ascii face count {count}"), header.into_bytes(), codes);
        let body = &t::ply_binary(false)[t::ply_binary_header(false, "4", "2").len()..];
        let bytes = [t::ply_binary_header(false, count, "2").as_bytes(), body].concat();
        // One vertex more reads the faces' bytes as a vertex: no way to tell.
        let codes = if count == "5" || count == "0" { OK_OR_BAD } else { BAD_INPUT };
        both(&mut cases, format!("binary vertex count {count}"), bytes, codes);
        let bytes = [t::ply_binary_header(false, "4", count).as_bytes(), body].concat();
        both(&mut cases, format!("binary face count {count}"), bytes, codes);
    }
    // An element of no properties: a count of 10^18 takes no bytes to
    // read, and must take no time either.
    for count in ["1000000000000000000", "18446744073709551615"] {
        let bytes = t::PLY_ASCII.replace("end_header", &format!("element nothing {count}\nend_header"));
        both(&mut cases, format!("empty element of {count}"), bytes.into_bytes(), OK);
    }
    // Lists: lengths past the body, of odd types.
    for (list, what) in [
        ("property list uint uint vertex_indices", "uint list of 4e9"),
        ("property list float uint vertex_indices", "float list length"),
        ("property list uchar double vertex_indices", "double indices"),
        ("property list int int vertex_indices", "negative list length"),
    ] {
        let mut b = t::ply_binary_header(false, "4", "1")
            .replace("property list uchar uint vertex_indices", list)
            .into_bytes();
        for p in [[-1.0f32, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]] {
            p.iter().for_each(|x| b.extend(x.to_le_bytes()));
        }
        match what {
            "uint list of 4e9" => b.extend(4_000_000_000u32.to_le_bytes()),
            "float list length" => b.extend(3.5f32.to_le_bytes()),
            "double indices" => {
                b.push(3);
                [0.0f64, 1.0, 1e300].iter().for_each(|x| b.extend(x.to_le_bytes()));
            }
            _ => b.extend((-3i32).to_le_bytes()),
        }
        b.extend([0u8; 12]);
        both(&mut cases, what.to_string(), b, BAD_INPUT);
    }
    for (what, from, to) in [
        ("index out of range", "3 0 2 3\n", "3 0 2 4\n"),
        ("negative index", "3 0 2 3\n", "3 0 2 -1\n"),
        ("index 2^32", "3 0 2 3\n", "3 0 2 4294967296\n"),
        ("index 1e300", "3 0 2 3\n", "3 0 2 1e300\n"),
        ("index nan", "3 0 2 3\n", "3 0 2 nan\n"),
        ("coordinate 1e400", "1 1 0 1 1", "1 1e400 0 1 1"),
        ("coordinate nan", "1 1 0 1 1", "1 nan 0 1 1"),
        ("coordinate inf", "1 1 0 1 1", "1 -inf 0 1 1"),
        ("coordinate word", "1 1 0 1 1", "1 one 0 1 1"),
        ("no end_header", "end_header\n", ""),
        ("property before element", "element vertex 4\n", "property float w\nelement vertex 4\n"),
        ("unknown format", "format ascii 1.0", "format ebcdic 1.0"),
        ("no format", "format ascii 1.0\n", ""),
        ("no x", "property float x\n", ""),
        ("no faces", "element face 2\nproperty list uchar int vertex_indices\n", ""),
        ("face without index list", "property list uchar int vertex_indices", "property int vertex_indices"),
        ("unknown type", "property float y", "property quad y"),
        ("binary claimed, text given", "format ascii 1.0", "format binary_little_endian 1.0"),
        ("no magic", "ply\n", "plx\n"),
        ("long list", "3 0 1 2\n", "255 0 1 2\n"),
    ] {
        let bytes = t::PLY_ASCII.replacen(from, to, 1);
        let codes = if what == "no faces" { OK_OR_BAD } else { BAD_INPUT };
        both(&mut cases, format!("ascii {what}"), bytes.into_bytes(), codes);
    }
    for (what, value) in [("NaN", f32::NAN), ("infinity", f32::INFINITY), ("largest", f32::MAX)] {
        let mut b = t::ply_binary(false);
        let at = t::ply_binary_header(false, "4", "2").len() + 4;
        b[at..at + 4].copy_from_slice(&value.to_le_bytes());
        let codes = if what == "largest" { OK_OR_BAD } else { BAD_INPUT };
        both(&mut cases, format!("binary coordinate {what}"), b, codes);
    }
    // Truncated anywhere.
    let ascii = t::PLY_ASCII.as_bytes();
    for cut in (3..ascii.len()).step_by(13) {
        let case = Case::render(
            c,
            format!("ascii truncated at {cut}"),
            "model.ply",
            vec![file("model.ply", &ascii[..cut])],
        );
        cases.push(case.codes(OK_OR_BAD).says_on_failure("model.ply"));
    }
    let binary = t::ply_binary(true);
    for cut in (3..binary.len()).step_by(7) {
        let case = Case::render(
            c,
            format!("binary truncated at {cut}"),
            "model.ply",
            vec![file("model.ply", &binary[..cut])],
        );
        cases.push(case.codes(OK_OR_BAD).says_on_failure("model.ply"));
    }
    cases
}

/// OFF counts that lie, faces of trillions of corners, bad numbers.
fn off() -> Vec<Case> {
    let c = "OFF";
    let mut cases = Vec::new();
    let mut push = |name: String, text: Vec<u8>, codes: &'static [i32], line: bool| {
        let case = Case::render(c, name, "model.off", vec![file("model.off", text)])
            .codes(codes)
            .says_on_failure("model.off");
        cases.push(if line { case.line_in("model.off") } else { case });
    };
    for counts in [
        "4000000000 2 0",
        "4 4000000000 0",
        "1000000000000000000 2 0",
        "4 1000000000000000000 0",
        "18446744073709551616 2 0",
        "-1 2 0",
        "4 -2 0",
        "4 2",
        "4",
        "",
        "four two zero",
        "5 2 0",
        "4 3 0",
    ] {
        // The edge count is optional.
        let codes = if counts == "4 2" { OK } else { BAD_INPUT };
        push(format!("counts '{counts}'"), t::OFF.replace("4 2 0", counts).into_bytes(), codes, true);
    }
    for (what, from, to, codes) in [
        ("face of 4e12 corners", "3 0 2 3", "4000000000000 0 2 3", BAD_INPUT),
        ("face of 2^64 corners", "3 0 2 3", "18446744073709551616 0 2 3", BAD_INPUT),
        ("face of -3 corners", "3 0 2 3", "-3 0 2 3", BAD_INPUT),
        ("index out of range", "3 0 2 3", "3 0 2 4", BAD_INPUT),
        ("negative index", "3 0 2 3", "3 0 2 -1", BAD_INPUT),
        ("index 2^32", "3 0 2 3", "3 0 2 4294967296", BAD_INPUT),
        ("coordinate 1e400", "1 1 0", "1 1e400 0", BAD_INPUT),
        ("coordinate nan", "1 1 0", "1 nan 0", BAD_INPUT),
        ("coordinate inf", "1 1 0", "1 inf 0", BAD_INPUT),
        ("coordinate 3e38", "1 1 0", "3e38 1 0", OK_OR_BAD),
        ("missing coordinate", "1 1 0", "1 1", BAD_INPUT),
        ("binary", "OFF\n", "OFF BINARY\n", BAD_INPUT),
        ("4D", "OFF\n", "4OFF\n", BAD_INPUT),
        ("not OFF", "OFF\n", "PLY\n", BAD_INPUT),
    ] {
        push(what.to_string(), t::OFF.replacen(from, to, 1).into_bytes(), codes, true);
    }
    push("not UTF-8".into(), [t::OFF.as_bytes(), b"\xff\xfe"].concat(), BAD_INPUT, false);
    let text = t::OFF.as_bytes();
    for cut in (1..text.len()).step_by(4) {
        push(format!("truncated at {cut}"), text[..cut].to_vec(), OK_OR_BAD, false);
    }
    cases
}

/// OBJ numbers and indices out of range, materials that make no sense.
fn obj() -> Vec<Case> {
    let c = "OBJ";
    let mut cases = Vec::new();
    let png = || file("tex.png", t::png(4, 4));
    // Errors name the file they are in: a material's, its library at the
    // line that defines it.
    let mut push = |name: String, obj: String, mtl: String, codes: &'static [i32], at: &str| {
        let case =
            Case::render(c, name, "model.obj", vec![file("model.obj", obj), file("model.mtl", mtl), png()]);
        let case = case.codes(codes).says_on_failure(at);
        cases.push(if at == "model.mtl" { case.line_in("model.mtl") } else { case });
    };
    for (what, from, to, codes) in [
        ("coordinate 1e400", "v 1 1 0", "v 1 1e400 0", BAD_INPUT),
        ("coordinate nan", "v 1 1 0", "v 1 nan 0", BAD_INPUT),
        ("coordinate inf", "v 1 1 0", "v 1 inf 0", BAD_INPUT),
        ("coordinate 3e38", "v 1 1 0", "v 3e38 1 0", OK_OR_BAD),
        ("coordinate word", "v 1 1 0", "v 1 one 0", BAD_INPUT),
        ("index 0", "f 1/1/1 3/3/1 4/4/1", "f 0/1/1 3/3/1 4/4/1", BAD_INPUT),
        ("index 5", "f 1/1/1 3/3/1 4/4/1", "f 5/1/1 3/3/1 4/4/1", BAD_INPUT),
        ("index -5", "f 1/1/1 3/3/1 4/4/1", "f -5/1/1 3/3/1 4/4/1", BAD_INPUT),
        ("index 2^32", "f 1/1/1 3/3/1 4/4/1", "f 4294967297/1/1 3/3/1 4/4/1", BAD_INPUT),
        ("index 2^64", "f 1/1/1 3/3/1 4/4/1", "f 18446744073709551617/1/1 3/3/1 4/4/1", BAD_INPUT),
        ("uv index 9", "f 1/1/1 3/3/1 4/4/1", "f 1/9/1 3/3/1 4/4/1", BAD_INPUT),
        ("normal index 9", "f 1/1/1 3/3/1 4/4/1", "f 1/1/9 3/3/1 4/4/1", BAD_INPUT),
        ("face of one vertex", "f 1/1/1 3/3/1 4/4/1", "f 1/1/1", OK_OR_BAD),
        ("face of words", "f 1/1/1 3/3/1 4/4/1", "f a b c", BAD_INPUT),
        ("unknown material", "usemtl red", "usemtl blue", OK),
        ("unknown statement", "usemtl red", "frobnicate 1 2 3\nusemtl red", OK_OR_BAD),
        ("emissive", "usemtl red", "usemtl glow", OK),
    ] {
        push(what.to_string(), t::OBJ.replacen(from, to, 1), t::MTL.to_string(), codes, "model.obj");
    }
    for (what, from, to, codes) in [
        ("Kd 1e400", "Kd 0.8 0.1 0.1", "Kd 1e400 0.1 0.1", OK_OR_BAD),
        ("Kd nan", "Kd 0.8 0.1 0.1", "Kd nan 0.1 0.1", OK_OR_BAD),
        ("Kd -1", "Kd 0.8 0.1 0.1", "Kd -1 0.1 0.1", OK_OR_BAD),
        ("Ke negative", "Ke 1 1 1", "Ke -1 1 1", BAD_INPUT),
        ("Ke 1e400", "Ke 1 1 1", "Ke 1e400 1 1", BAD_INPUT),
        ("Ke nan", "Ke 1 1 1", "Ke nan 1 1", BAD_INPUT),
        ("Ni 0", "Kd 0.8 0.1 0.1", "Kd 0.8 0.1 0.1\nNi 0\nd 0.5", OK_OR_BAD),
        ("Ns -1", "Kd 0.8 0.1 0.1", "Kd 0.8 0.1 0.1\nNs -1\nKs 1 1 1", OK_OR_BAD),
        ("map without file", "map_Kd tex.png", "map_Kd", OK_OR_BAD),
        ("map options only", "map_Kd tex.png", "map_Kd -s 1 1 1 -o", OK_OR_BAD),
        ("not UTF-8", "newmtl red", "newmtl r\u{1}d", OK_OR_BAD),
    ] {
        let emissive = if what.starts_with("Ke") {
            t::OBJ.replace("usemtl red", "usemtl glow")
        } else {
            t::OBJ.to_string()
        };
        let case_mtl = t::MTL.replacen(from, to, 1).replace('\u{1}', "\u{fffd}");
        let at = if what.starts_with("Ke") { "model.mtl" } else { "model.obj" };
        push(format!("mtl {what}"), emissive, case_mtl, codes, at);
    }
    let obj = t::OBJ.as_bytes();
    for cut in (1..obj.len()).step_by(9) {
        let case = Case::render(
            c,
            format!("truncated at {cut}"),
            "model.obj",
            vec![file("model.obj", &obj[..cut]), file("model.mtl", t::MTL), png()],
        );
        cases.push(case.codes(OK_OR_BAD).says_on_failure("model.obj"));
    }
    let case = Case::render(
        c,
        "not UTF-8",
        "model.obj",
        vec![
            file("model.obj", [t::OBJ.as_bytes(), b"v \xff 1 1\n"].concat()),
            file("model.mtl", t::MTL),
            png(),
        ],
    );
    cases.push(case.codes(OK_OR_BAD).says_on_failure("model.obj"));
    cases
}

/// glTF documents whose numbers, indices and sizes lie.
fn gltf() -> Vec<Case> {
    let c = "glTF";
    let mut cases = Vec::new();
    let png = || file("tex.png", t::png(4, 4));
    let mut push = |name: String, json: String, codes: &'static [i32]| {
        let case = Case::render(
            c,
            name,
            "model.gltf",
            vec![file("model.gltf", json), file("model.bin", t::gltf_bin()), png()],
        );
        cases.push(case.codes(codes).says_on_failure("model.gltf"));
    };
    for (what, from, to, codes) in [
        ("byteLength 1e18", "\"byteLength\":68", "\"byteLength\":1000000000000000000", BAD_INPUT),
        ("byteLength 2^64-1", "\"byteLength\":68", "\"byteLength\":18446744073709551615", BAD_INPUT),
        ("byteLength 2^64", "\"byteLength\":68", "\"byteLength\":18446744073709551616", BAD_INPUT),
        ("byteLength -1", "\"byteLength\":68", "\"byteLength\":-1", BAD_INPUT),
        ("byteLength 1e400", "\"byteLength\":68", "\"byteLength\":1e400", BAD_INPUT),
        ("byteLength 0", "\"byteLength\":68", "\"byteLength\":0", OK_OR_BAD),
        ("view offset 2^64-1", "\"byteOffset\":36", "\"byteOffset\":18446744073709551615", BAD_INPUT),
        ("view offset 2^63", "\"byteOffset\":36", "\"byteOffset\":9223372036854775808", BAD_INPUT),
        ("view length 2^32-1", "\"byteLength\":36", "\"byteLength\":4294967295", BAD_INPUT),
        ("view of buffer 5", "{\"buffer\":0,\"byteOffset\":0", "{\"buffer\":5,\"byteOffset\":0", BAD_INPUT),
        ("view stride 1", "\"byteLength\":36}", "\"byteLength\":36,\"byteStride\":4}", BAD_INPUT),
        ("view stride 2^31", "\"byteLength\":36}", "\"byteLength\":36,\"byteStride\":2147483648}", BAD_INPUT),
        ("position count 4e9", "\"count\":3,\"type\":\"VEC3\"", "\"count\":4000000000,\"type\":\"VEC3\"", BAD_INPUT),
        ("position count 2^62", "\"count\":3,\"type\":\"VEC3\"", "\"count\":4611686018427387904,\"type\":\"VEC3\"", BAD_INPUT),
        ("position count 0", "\"count\":3,\"type\":\"VEC3\"", "\"count\":0,\"type\":\"VEC3\"", BAD_INPUT),
        ("index count 4e9", "\"count\":3,\"type\":\"SCALAR\"", "\"count\":4000000000,\"type\":\"SCALAR\"", BAD_INPUT),
        ("index count 4", "\"count\":3,\"type\":\"SCALAR\"", "\"count\":4,\"type\":\"SCALAR\"", OK_OR_BAD),
        ("accessor offset 2^63", "{\"bufferView\":0,", "{\"bufferView\":0,\"byteOffset\":9223372036854775808,", BAD_INPUT),
        ("accessor offset 30", "{\"bufferView\":0,", "{\"bufferView\":0,\"byteOffset\":30,", BAD_INPUT),
        ("accessor of view 9", "{\"bufferView\":0,", "{\"bufferView\":9,", BAD_INPUT),
        ("positions as bytes", "\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"", "\"componentType\":5121,\"count\":3,\"type\":\"VEC3\"", BAD_INPUT),
        ("positions as MAT4", "\"type\":\"VEC3\"", "\"type\":\"MAT4\"", BAD_INPUT),
        ("indices as floats", "\"componentType\":5123,", "\"componentType\":5126,", BAD_INPUT),
        ("component type 9999", "\"componentType\":5123,", "\"componentType\":9999,", BAD_INPUT),
        ("index accessor 9", "\"indices\":2", "\"indices\":9", BAD_INPUT),
        ("mesh 9", "{\"mesh\":0}", "{\"mesh\":9}", BAD_INPUT),
        ("scene 9", "\"scene\":0", "\"scene\":9", BAD_INPUT),
        ("material 9", "\"material\":0", "\"material\":9", BAD_INPUT),
        ("texture 9", "{\"index\":0}", "{\"index\":9}", BAD_INPUT),
        ("image 9", "{\"source\":0}", "{\"source\":9}", BAD_INPUT),
        ("node cycle", "{\"mesh\":0}", "{\"mesh\":0,\"children\":[0]}", BAD_INPUT),
        ("node cycle of two", "{\"mesh\":0}", "{\"mesh\":0,\"children\":[1]},{\"children\":[0]", BAD_INPUT),
        ("child 9", "{\"mesh\":0}", "{\"mesh\":0,\"children\":[9]}", BAD_INPUT),
        ("yfov 0", "\"yfov\":0.8", "\"yfov\":0", BAD_INPUT),
        ("yfov -1", "\"yfov\":0.8", "\"yfov\":-1", BAD_INPUT),
        ("yfov 4", "\"yfov\":0.8", "\"yfov\":4", BAD_INPUT),
        ("yfov 1e39", "\"yfov\":0.8", "\"yfov\":1e39", BAD_INPUT),
        ("aspect 0", "\"aspectRatio\":1.0", "\"aspectRatio\":0", OK_OR_BAD),
        ("aspect 1e38", "\"aspectRatio\":1.0", "\"aspectRatio\":1e38", OK_OR_BAD),
        ("znear 0", "\"znear\":0.01", "\"znear\":0", OK_OR_BAD),
        ("translation 1e39", "\"translation\":[0,0,3]", "\"translation\":[0,0,1e39]", BAD_INPUT),
        ("scale 0", "{\"mesh\":0}", "{\"mesh\":0,\"scale\":[0,0,0]}", OK_OR_BAD),
        ("matrix of 1e38", "{\"mesh\":0}", "{\"mesh\":0,\"matrix\":[1e38,0,0,0,0,1e38,0,0,0,0,1e38,0,0,0,0,1]}", OK_OR_BAD),
        ("emission -1", "\"emissiveFactor\":[0.1,0.1,0.1]", "\"emissiveFactor\":[-1,0.1,0.1]", BAD_INPUT),
        ("emission 1e39", "\"emissiveFactor\":[0.1,0.1,0.1]", "\"emissiveFactor\":[1e39,0.1,0.1]", BAD_INPUT),
        ("emission strength -5", "\"emissiveFactor\":[0.1,0.1,0.1]", "\"emissiveFactor\":[0.1,0.1,0.1],\"extensions\":{\"KHR_materials_emissive_strength\":{\"emissiveStrength\":-5}}", BAD_INPUT),
        ("base colour 1e39", "[0.8,0.8,0.8,1]", "[1e39,0.8,0.8,1]", OK_OR_BAD),
        ("base colour -1", "[0.8,0.8,0.8,1]", "[-1,0.8,0.8,1]", OK_OR_BAD),
        ("version 1.0", "\"version\":\"2.0\"", "\"version\":\"1.0\"", OK_OR_BAD),
        ("version 99", "\"version\":\"2.0\"", "\"version\":\"99.0\"", OK_OR_BAD),
        ("no asset", "{\"asset\":{\"version\":\"2.0\"},", "{", BAD_INPUT),
        ("JSON array", "{\"asset\"", "[{\"asset\"", BAD_INPUT),
        ("data URI not base64", "\"uri\":\"tex.png\"", "\"uri\":\"data:image/png;base64,!!!!\"", OK),
        ("image data URI of text", "\"uri\":\"tex.png\"", "\"uri\":\"data:image/png;base64,aGVsbG8=\"", OK),
    ] {
        push(what.to_string(), t::gltf().replacen(from, to, 1), codes);
    }
    // Scene graphs deeper than any stack.
    let mut nodes = String::from("{\"mesh\":0,\"children\":[2]},{\"camera\":0,\"translation\":[0,0,3]}");
    for i in 2..100_000 {
        nodes.push_str(&format!(",{{\"children\":[{}]}}", i + 1));
    }
    nodes.push_str(",{\"mesh\":0}");
    let deep = t::gltf().replacen("{\"mesh\":0},{\"camera\":0,\"translation\":[0,0,3]}", &nodes, 1);
    push("node chain of 100000".into(), deep, OK_OR_BAD);
    let nested = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    push(
        "JSON nested 100000 deep".into(),
        t::gltf().replacen("\"extras\"", "", 0).replacen(
            "\"scene\":0",
            &format!("\"extras\":{nested},\"scene\":0"),
            1,
        ),
        OK_OR_BAD,
    );
    for bad in [
        "data:application/octet-stream;base64,!!!!",
        "data:application/octet-stream;base64,AAAA",
        "data:,",
        "data:",
    ] {
        let json = t::GLTF.replace("BUFFER_URI", bad);
        push(format!("buffer data URI '{bad}'"), json, BAD_INPUT);
    }
    let json = t::gltf();
    for cut in (1..json.len()).step_by(23) {
        push(format!("truncated at {cut}"), json[..cut].to_string(), OK_OR_BAD);
    }
    let bin = t::gltf_bin();
    for cut in (0..bin.len()).step_by(8) {
        let case = Case::render(
            c,
            format!("buffer truncated at {cut}"),
            "model.gltf",
            vec![file("model.gltf", t::gltf()), file("model.bin", &bin[..cut]), png()],
        );
        cases.push(case.bad("model.gltf"));
    }
    let glb = t::glb();
    for cut in (1..glb.len()).step_by(37) {
        let case = Case::render(
            c,
            format!("GLB truncated at {cut}"),
            "model.glb",
            vec![file("model.glb", &glb[..cut]), png()],
        );
        cases.push(case.codes(OK_OR_BAD).says_on_failure("model.glb"));
    }
    for (what, at, value) in [
        ("GLB length 2^32-1", 8, u32::MAX),
        ("GLB JSON chunk length 2^32-1", 12, u32::MAX),
        ("GLB JSON chunk length 0", 12, 0),
        ("GLB version 1", 4, 1),
    ] {
        let mut b = glb.clone();
        b[at..at + 4].copy_from_slice(&value.to_le_bytes());
        let case = Case::render(c, what, "model.glb", vec![file("model.glb", b), png()]);
        cases.push(case.bad("model.glb"));
    }
    cases
}

/// Texture and environment images truncated, or claiming sizes no memory holds.
fn images(scratch: &std::path::Path) -> Vec<Case> {
    let c = "images";
    let mut cases = Vec::new();
    let png = t::png(4, 4);
    let exr = t::exr(scratch);
    let mut push = |name: String, image: &str, bytes: Vec<u8>| {
        let case =
            Case::render(c, format!("texture {name}"), "scene.pbrt", image_scene(image, bytes.clone()));
        cases.push(case.codes(OK_OR_BAD).says(image));
        let case = Case::render(c, format!("environment {name}"), "scene.pbrt", envmap_scene(image, bytes));
        cases.push(case.codes(OK_OR_BAD).says(image).says_on_failure(at(t::STATEMENT_LINE)));
    };
    for cut in (1..png.len()).step_by(17) {
        push(format!("PNG truncated at {cut}"), "tex.png", png[..cut].to_vec());
    }
    for cut in (1..exr.len()).step_by(61) {
        push(format!("EXR truncated at {cut}"), "tex.exr", exr[..cut].to_vec());
    }
    let idat = {
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        std::io::Write::write_all(&mut z, &[0u8; 64]).unwrap();
        z.finish().unwrap()
    };
    for (w, h) in
        [(100_000u32, 100_000u32), (65535, 65535), (0, 4), (1, 0x7fff_ffff), (0x7fff_ffff, 0x7fff_ffff)]
    {
        push(format!("PNG claiming {w}x{h}"), "tex.png", t::png_with(w, h, &idat));
    }
    // The data window of the EXR (its max corner), claiming billions of pixels.
    let window = exr.windows(10).position(|w| w == b"dataWindow").expect("an EXR data window");
    let max_at = window + b"dataWindow\0box2i\0".len() + 4 + 8;
    for (x, y) in [(0x7fff_fff0i32, 3i32), (100_000, 100_000), (3, -5), (-0x7fff_ffff, 3)] {
        let mut b = exr.clone();
        b[max_at..max_at + 4].copy_from_slice(&x.to_le_bytes());
        b[max_at + 4..max_at + 8].copy_from_slice(&y.to_le_bytes());
        push(format!("EXR data window to {x},{y}"), "tex.exr", b);
    }
    push("PFM".into(), "tex.pfm", t::pfm());
    push("PNG named .exr".into(), "tex.exr", png.clone());
    push("EXR named .png".into(), "tex.png", exr.clone());
    push("NaN EXR".into(), "tex.exr", {
        let path = scratch.join("nan.exr");
        exr::prelude::write_rgb_file(&path, 2, 2, |_, _| (f32::NAN, 1.0f32, f32::INFINITY)).unwrap();
        std::fs::read(path).unwrap()
    });
    cases
}

/// gzip data that inflates past any sense, or is not gzip at all.
fn gzip() -> Vec<Case> {
    let c = "gzip";
    let mut cases = Vec::new();
    let scene_bomb = t::gzip_bomb(t::pbrt().as_bytes(), b' ', 256);
    let ply_bomb = t::gzip_bomb(t::PLY_ASCII.as_bytes(), b' ', 256);
    let members: Vec<u8> = (0..2000).flat_map(|_| t::gzip(&vec![b'\n'; 64 << 10])).collect();
    for (what, name, bytes) in [
        ("scene bomb", "scene.pbrt.gz", scene_bomb.clone()),
        ("scene bomb of 2000 members", "scene.pbrt.gz", members),
        ("PLY bomb", "model.ply.gz", ply_bomb.clone()),
        ("PLY bomb named .ply", "model.ply", ply_bomb.clone()),
        ("scene truncated gzip", "scene.pbrt.gz", t::gzip(t::pbrt().as_bytes())[..40].to_vec()),
        ("scene not gzip", "scene.pbrt.gz", t::pbrt().into_bytes()),
        ("scene gzip of gzip", "scene.pbrt.gz", t::gzip(&t::gzip(t::pbrt().as_bytes()))),
        ("PLY truncated gzip", "model.ply.gz", t::gzip(&t::ply_binary(false))[..30].to_vec()),
        ("PLY gzip magic only", "model.ply.gz", vec![0x1f, 0x8b]),
    ] {
        let case = Case::render(c, what, name, vec![file(name, bytes)]);
        cases.push(case.bad(name));
    }
    let statement = "Shape \"plymesh\" \"string filename\" \"model.ply.gz\"";
    let case = Case::render(
        c,
        "plymesh bomb",
        "scene.pbrt",
        vec![file("scene.pbrt", t::pbrt_with(statement)), file("model.ply.gz", ply_bomb)],
    );
    cases.push(case.bad(at(t::STATEMENT_LINE)).says("model.ply.gz"));
    let case = Case::render(
        c,
        "Include bomb",
        "scene.pbrt",
        vec![file("scene.pbrt", t::pbrt_with("Include \"more.pbrt.gz\"")), file("more.pbrt.gz", scene_bomb)],
    );
    cases.push(case.bad("more.pbrt.gz"));
    cases
}

/// Geometry that multiplies past any memory: subdivision levels and grids.
fn sizes() -> Vec<Case> {
    let c = "subdivision";
    let mut cases = Vec::new();
    for (n, levels, codes) in [
        (1usize, "8", OK),
        (100, "8", REFUSED),
        (100, "7", REFUSED),
        (100, "9", BAD_INPUT),
        (1, "-1", BAD_INPUT),
        (1, "4294967297", BAD_INPUT),
    ] {
        let statement = t::grid_mesh(n, "loopsubdiv").replacen(
            "\"point3 P\"",
            &format!("\"integer levels\" [ {levels} ] \"point3 P\""),
            1,
        );
        let case = Case::render(
            c,
            format!("loopsubdiv levels {levels} of {} triangles", 2 * n * n),
            "scene.pbrt",
            scene(t::pbrt_with(&statement)),
        );
        cases.push(case.codes(codes).says_on_failure(at(t::STATEMENT_LINE)));
    }
    cases
}

/// What a refusal of `flag value` names: the flag (negative numbers such
/// as `-1` or `-0.1` are values), or for other values that look like flags
/// (`-inf`, `-1G`), that (the argument parser's "unexpected argument '-…'").
fn named<'a>(flag: &'a str, value: &'a str) -> &'a str {
    let negative_number = value.len() > 1 && value[1..].chars().all(|c| c.is_ascii_digit() || c == '.');
    if value.starts_with('-') && !negative_number {
        "unexpected argument '-"
    } else {
        flag
    }
}

/// Command lines: sizes that wrap, numbers that are none, outputs that
/// cannot be written, generated scenes larger than the machine.
fn cli(scratch: &std::path::Path) -> Vec<Case> {
    let c = "arguments";
    let mut cases = Vec::new();
    let files = || scene(t::pbrt());
    let render = |extra: &[&str]| {
        let mut a = vec!["render", "scene.pbrt", "-o", "out.png", "-q", "--device", "cpu"];
        a.extend_from_slice(extra);
        a.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    let mut push =
        |name: String, a: Vec<String>, files: Vec<(String, Entry)>, codes: &'static [i32], says: &[&str]| {
            let a: Vec<&str> = a.iter().map(String::as_str).collect();
            let mut case = Case::cli(c, name, &a, files).codes(codes);
            for s in says {
                case = case.says(*s);
            }
            cases.push(case);
        };
    for res in [
        "65536x65536",
        "92682x46341",
        "100000x100000",
        "4294967296x1",
        "1x4294967296",
        "0x16",
        "16x0",
        "-16x16",
        "16x",
        "x16",
        "16x16x16",
        "16",
        "16*16",
        "1x268435457",
        "16384x16385",
        "",
        "0x0",
        "nanxnan",
    ] {
        push(
            format!("--res {res}"),
            render(&["--res", res, "--spp", "1"]),
            files(),
            BAD_INPUT,
            &[named("--res", res)],
        );
    }
    for spp in ["0", "-1", "4294967296", "nan", "1e3", ""] {
        push(format!("--spp {spp}"), render(&["--spp", spp]), files(), BAD_INPUT, &[named("--spp", spp)]);
    }
    for threads in ["100000", "0", "-1", "18446744073709551616", "many"] {
        push(
            format!("--threads {threads}"),
            render(&["--threads", threads]),
            files(),
            BAD_INPUT,
            &[named("--threads", threads)],
        );
    }
    for ao in ["nan", "inf", "0", "-1", "1e400", "-0", "x"] {
        push(
            format!("--ao {ao}"),
            render(&["--ao", ao, "--res", "16x16"]),
            files(),
            BAD_INPUT,
            &[named("--ao", ao)],
        );
    }
    for (flag, value) in [
        ("--max-depth", "-1"),
        ("--max-depth", "4294967296"),
        ("--seed", "-1"),
        ("--seed", "4294967296"),
        ("--wave-size", "0"),
        ("--wave-size", "4294967296"),
        ("--streams", "0"),
        ("--streams", "9"),
        ("--device", "cuda:99999999999"),
        ("--device", "gpu"),
        ("--device-memory", "-1G"),
        ("--device-memory", "99999999999999999999G"),
        ("--device-memory", "nanG"),
        ("--light-sampler", "uniform"),
    ] {
        let mut a = render(&["--res", "16x16"]);
        if flag == "--device" {
            a.retain(|s| s != "--device" && s != "cpu");
        }
        a.extend([flag.to_string(), value.to_string()]);
        push(format!("{flag} {value}"), a, files(), REFUSED, &[named(flag, value)]);
    }
    push(
        "--max-depth 4294967295 renders".into(),
        render(&["--max-depth", "4294967295", "--res", "16x16", "--spp", "1"]),
        files(),
        OK,
        &[],
    );
    push(
        "--wave-size 1 renders".into(),
        render(&["--wave-size", "1", "--res", "4x4", "--spp", "1"]),
        files(),
        OK,
        &[],
    );
    // Terrains past 32-bit vertex indices are bad input; one within them
    // but larger than any host's memory does not fit.
    for (source, codes, says) in [
        ("landscape:4294967295", BAD_INPUT, "32-bit indices"),
        ("landscape:4294967295:4294967295", BAD_INPUT, "32-bit indices"),
        ("landscape:100000000", BAD_INPUT, "32-bit indices"),
        ("landscape:260000", TOO_BIG, "host memory"),
    ] {
        let a = args(&[
            "render", source, "-o", "out.png", "--res", "16x16", "--spp", "1", "-q", "--device", "cpu",
        ]);
        push(source.to_string(), a, vec![], codes, &[says]);
        push(format!("info {source}"), args(&["info", source]), vec![], codes, &[says]);
    }
    for source in [
        "landscape:0",
        "landscape:-1",
        "landscape:4294967296",
        "landscape:",
        "landscape:1:2:3",
        "landscape:1:x",
    ] {
        let a = args(&["render", source, "-o", "out.png", "-q", "--device", "cpu"]);
        push(source.to_string(), a, vec![], BAD_INPUT, &[source]);
    }
    // Outputs that cannot be written: refused before loading, naming them.
    for (what, output, extra, says) in [
        ("unknown extension", "out.tga", None, "out.tga"),
        ("no extension", "out", None, "out"),
        ("missing folder", "missing/out.png", None, "missing"),
        ("a folder", "dir.png", Some(("dir.png", Entry::Dir)), "dir.png"),
        ("inside a file", "scene.pbrt/out.png", None, "scene.pbrt"),
        ("empty name", "", None, "output"),
        ("a pipe", "pipe.png", Some(("pipe.png", Entry::Fifo)), "pipe.png"),
    ] {
        let mut f = files();
        if let Some((name, entry)) = extra {
            f.push((name.to_string(), entry));
        }
        let a = args(&[
            "render",
            "scene.pbrt",
            "-o",
            output,
            "--res",
            "16x16",
            "--spp",
            "1",
            "-q",
            "--device",
            "cpu",
        ]);
        push(format!("output {what}"), a, f, if what == "a pipe" { REFUSED } else { BAD_INPUT }, &[says]);
    }
    // The scene's own Film filename, when no -o is given, gets the same checks.
    for name in ["film.tga", "missing/film.png", "../film.png", "/tmp/film.png"] {
        let text = t::pbrt().replace("film.png", name);
        let a = args(&["render", "scene.pbrt", "--res", "16x16", "--spp", "1", "-q", "--device", "cpu"]);
        push(format!("Film filename {name}"), a, scene(text), BAD_INPUT, &[name]);
    }
    // compare: gates that cannot fail, files that are not renders.
    let exr = t::exr(scratch);
    let images = || {
        vec![
            file("a.exr", exr.clone()),
            file("b.exr", exr.clone()),
            file("c.png", t::png(4, 4)),
            file("d.exr", &exr[..exr.len() / 2]),
        ]
    };
    for limit in ["nan", "inf", "-inf", "-0.1", "1e400", "x"] {
        push(
            format!("compare --max-mean-diff {limit}"),
            args(&["compare", "a.exr", "b.exr", "--max-mean-diff", limit]),
            images(),
            BAD_INPUT,
            &[named("--max-mean-diff", limit)],
        );
    }
    push(
        "compare equal".into(),
        args(&["compare", "a.exr", "b.exr", "--max-mean-diff", "0"]),
        images(),
        OK,
        &[],
    );
    for (b, says) in
        [("missing.exr", "missing.exr"), ("c.png", "c.png"), ("d.exr", "d.exr"), ("/dev/zero", "/dev/zero")]
    {
        push(format!("compare with {b}"), args(&["compare", "a.exr", b]), images(), BAD_INPUT, &[says]);
    }
    // gen: sizes and outputs.
    for (what, a, codes, says) in [
        ("growth 0", &["gen", "landscape", "--growth", "0"][..], BAD_INPUT, "--growth"),
        ("growth 2^32", &["gen", "landscape", "--growth", "4294967296"], BAD_INPUT, "--growth"),
        ("detail nan", &["gen", "landscape", "--detail", "nan"], BAD_INPUT, "--detail"),
        ("detail inf", &["gen", "landscape", "--detail", "inf"], BAD_INPUT, "--detail"),
        ("detail 0", &["gen", "landscape", "--detail", "0"], BAD_INPUT, "--detail"),
        ("detail -1", &["gen", "landscape", "--detail", "-1"], BAD_INPUT, "--detail"),
        ("detail 1e30", &["gen", "landscape", "--detail", "1e30", "-o", "land.pbrt"], BAD_INPUT, "--detail"),
        (
            "growth 2^32-1 written",
            &["gen", "landscape", "--growth", "4294967295", "-o", "land.pbrt"],
            BAD_INPUT,
            "32-bit indices",
        ),
        (
            "growth 260000 written",
            &["gen", "landscape", "--growth", "260000", "-o", "land.pbrt"],
            TOO_BIG,
            "host memory",
        ),
        ("output in missing folder", &["gen", "landscape", "-o", "missing/land.pbrt"], BAD_INPUT, "missing"),
        ("output a folder", &["gen", "landscape", "-o", "scene.pbrt/x.pbrt"], BAD_INPUT, "scene.pbrt"),
        ("unknown scene", &["gen", "island"], BAD_INPUT, "island"),
    ] {
        push(format!("gen {what}"), args(a), files(), codes, &[says]);
    }
    // bench: sizes past memory.
    for (what, a) in [
        (
            "triangles 2^64-1",
            &["bench", "--device", "cpu", "--triangles", "18446744073709551615", "--runs", "1"][..],
        ),
        ("triangles 2^40", &["bench", "--device", "cpu", "--triangles", "1099511627776", "--runs", "1"]),
        ("runs 0", &["bench", "--device", "cpu", "--triangles", "100", "--runs", "0", "--spp", "1"]),
        ("spp 0", &["bench", "--device", "cpu", "--triangles", "100", "--spp", "0"]),
    ] {
        push(format!("bench {what}"), args(a), vec![], REFUSED, &[]);
    }
    // info on what render refuses.
    push(
        "info of a pipe".into(),
        args(&["info", "scene.pbrt"]),
        vec![("scene.pbrt".into(), Entry::Fifo)],
        BAD_INPUT,
        &["scene.pbrt"],
    );
    push("unknown command".into(), args(&["paint"]), vec![], BAD_INPUT, &["paint"]);
    push(
        "unknown format".into(),
        args(&["render", "scene.xyz", "-o", "out.png"]),
        vec![file("scene.xyz", "x")],
        BAD_INPUT,
        &["scene.xyz"],
    );
    cases
}
