//! The `psr` program as a user meets it: file names it refuses, exit statuses, and the help text
//! that promises a PoissonRecon equivalent for every option.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const PSR: &str = env!("CARGO_BIN_EXE_psr");

/// The shipped sample cloud (5,210 points; depth 4 reconstructs it in milliseconds).
fn kitten() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/data/kitten_cgal.ply")
}

/// A fresh, empty directory of this test's own.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("psr-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn psr(args: &[&str]) -> Output {
    Command::new(PSR)
        .args(args)
        .output()
        .expect("the psr binary runs")
}

/// Runs the program on `input`, writing `output`, with the options `extra`.
fn psr_on(input: &Path, output: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "--in",
        input.to_str().unwrap(),
        "--out",
        output.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    psr(&args)
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Proves: an output name whose extension psr does not write is refused before anything runs,
/// with a message naming the option, the extensions accepted and the one given.
#[test]
fn an_unknown_output_extension_is_a_usage_error_listing_the_accepted_ones() {
    let dir = scratch("out-ext");
    let kitten = kitten();
    for (name, given) in [
        ("mesh.stl", ", not .stl"),
        ("mesh.off", ", not .off"),
        ("mesh.ply.gz", ", not .gz"),
        ("mesh", "one of those"),
    ] {
        let out_path = dir.join(name);
        let out = psr_on(&kitten, &out_path, &["--depth", "4"]);
        let message = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "--out {name}: {message}");
        assert!(
            message.contains("--out")
                && message.contains("psr writes meshes to .ply or .obj files")
                && message.contains(given),
            "--out {name}: the message should name the option, the extensions psr writes and \
             the one given: {message}"
        );
        assert!(!out_path.exists(), "--out {name} was written anyway");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: an input name whose extension psr does not read is refused, listing the
/// extensions it reads (PoissonRecon would read it as ASCII whatever it holds).
#[test]
fn an_unknown_input_extension_is_a_usage_error_listing_the_accepted_ones() {
    let dir = scratch("in-ext");
    let out_path = dir.join("mesh.ply");
    for name in ["cloud.pts", "cloud.txt", "cloud"] {
        let input = dir.join(name);
        std::fs::write(&input, "0 0 0 0 0 1\n").unwrap();
        let out = psr_on(&input, &out_path, &[]);
        let message = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{name}: {message}");
        assert!(
            message.contains("--in")
                && message
                    .contains("psr reads point clouds from .ply, .bnpts, .npts or .xyz files"),
            "{name}: {message}"
        );
        assert!(!out_path.exists());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ply_names_in_any_case_are_accepted_and_reconstructed() {
    let dir = scratch("ply-case");
    let input = dir.join("KITTEN.PLY");
    std::fs::copy(kitten(), &input).unwrap();
    let output = dir.join("Mesh.Ply");
    let out = psr_on(&input, &output, &["--depth", "4", "--quiet"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let bytes = std::fs::read(&output).expect("the mesh was written");
    assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_parameter_out_of_range_is_a_usage_error_naming_the_option() {
    let dir = scratch("range");
    let kitten = kitten();
    let out_path = dir.join("mesh.ply");
    let out = psr_on(&kitten, &out_path, &["--depth", "0"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--depth"), "{}", stderr(&out));
    assert!(!out_path.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: --width chooses the depth (the summary and --verbose say which), overriding
/// --depth, and a width that is not > 0 is a usage error naming --width.
#[test]
fn a_width_chooses_the_depth_and_the_summary_says_which() {
    let dir = scratch("width");
    let kitten = kitten();
    let out_path = dir.join("mesh.ply");
    // The kitten's cube side, as psr computes it: the longest side of its box × 1.1.
    let cloud = psr::ply::read_point_cloud(&kitten).unwrap();
    let side = (0..3)
        .map(|a| {
            let (lo, hi) = cloud
                .positions
                .iter()
                .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
                    (lo.min(p[a] as f64), hi.max(p[a] as f64))
                });
            hi - lo
        })
        .fold(0.0, f64::max)
        * 1.1f32 as f64;
    let width = side / 100.0; // 2^6 < 100 <= 2^7: depth 7
    let out = psr_on(
        &kitten,
        &out_path,
        &["--depth", "3", "--width", &width.to_string(), "--verbose"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("points, depth 7"),
        "the summary names the depth: {}",
        stderr(&out)
    );
    assert!(
        stderr(&out).contains("psr: depth 7 used"),
        "{}",
        stderr(&out)
    );
    for bad in ["--width=0", "--width=-1", "--width=nan"] {
        let out = psr_on(&kitten, &out_path, &[bad]);
        assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
        assert!(stderr(&out).contains("--width"), "{}", stderr(&out));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_missing_input_file_is_a_run_error() {
    let dir = scratch("missing");
    let out = psr(&[
        "--in",
        dir.join("absent.ply").to_str().unwrap(),
        "--out",
        dir.join("mesh.ply").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--help` split into one entry per option: (the option's long name, its whole help text).
fn help_entries() -> Vec<(String, String)> {
    let out = psr(&["--help"]);
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    let options = help
        .split_once("\nOptions:\n")
        .expect("an Options section")
        .1;
    let mut entries: Vec<(String, String)> = Vec::new();
    for line in options.lines() {
        let trimmed = line.trim_start();
        let indent = line.len() - trimmed.len();
        if (2..=6).contains(&indent) && trimmed.starts_with('-') {
            let long = trimmed
                .split([',', ' '])
                .map(str::trim)
                .find(|word| word.starts_with("--"))
                .expect("every option has a long name")
                .to_string();
            entries.push((long, String::new()));
        } else if indent == 0 && !trimmed.is_empty() {
            break; // the text after the options
        } else if let Some((_, text)) = entries.last_mut() {
            text.push(' ');
            text.push_str(trimmed);
        }
    }
    entries
}

/// `--boundary`'s help gives each kind its PoissonRecon `--bType` number, as PoissonRecon's
/// source numbers them (`BoundaryType` + 1: free 1, Dirichlet 2, Neumann 3), and the parser
/// takes each kind by name.
#[test]
fn boundary_help_gives_each_kind_its_btype_number() {
    let entries = help_entries();
    let (_, text) = entries
        .iter()
        .find(|(name, _)| name == "--boundary")
        .expect("--boundary in --help");
    for kind in ["3 = neumann", "1 = free", "2 = dirichlet"] {
        assert!(
            text.contains(kind),
            "--boundary's help lacks {kind}: {text}"
        );
    }
    assert!(
        text.contains("possible values: neumann, free, dirichlet"),
        "{text}"
    );
}

#[test]
fn help_gives_every_option_its_poissonrecon_equivalent() {
    let entries = help_entries();
    let names: Vec<&str> = entries.iter().map(|(name, _)| name.as_str()).collect();
    for (name, text) in &entries {
        if name == "--help" || name == "--version" {
            continue;
        }
        assert!(
            text.contains("PoissonRecon:"),
            "{name}'s help does not say its PoissonRecon equivalent: {text}"
        );
    }
    // The equivalents themselves (PoissonRecon 18.75's option names).
    let expected = [
        ("--in", "--in"),
        ("--out", "--out"),
        ("--depth", "--depth"),
        ("--width", "--width"),
        ("--full-depth", "--fullDepth"),
        ("--kernel-depth", "--kernelDepth"),
        ("--samples-per-node", "--samplesPerNode"),
        ("--scale", "--scale"),
        ("--point-weight", "--pointWeight"),
        ("--screening-follows-noise", "none"),
        ("--degree", "--degree"),
        ("--threads", "none"),
        ("--iters", "--iters"),
        ("--tolerance", "--cgAccuracy"),
        ("--boundary", "--bType"),
        ("--splatting", "none"),
        ("--vertices", "none"),
        ("--normals", "none"),
        ("--neighbors", "none"),
        ("--orientation", "none"),
        ("--reconstruction-iterations", "none"),
        ("--viewpoint", "none"),
        ("--confidence", "--confidence"),
        ("--no-density", "--density"),
        ("--trim", "SurfaceTrimmer --trim"),
        ("--trim-depth", "SurfaceTrimmer --trim"),
        ("--trim-density", "none"),
        ("--trim-quantile", "none"),
        ("--min-piece-area", "SurfaceTrimmer --aRatio"),
        ("--min-piece-triangles", "none"),
        ("--no-attributes", "none"),
        ("--colors", "--colors"),
        ("--transform", "--xForm"),
        ("--double", "--double"),
        ("--ascii", "--ascii"),
        ("--vertex-normals", "--normals"),
        ("--min-component-samples", "none"),
        ("--quiet", "none"),
        ("--verbose", "--verbose"),
        ("--grid", "--grid"),
        ("--grid-resolution", "none"),
        ("--grid-box", "none"),
        ("--max-memory", "none"),
        ("--out-of-core", "none"),
        ("--slabs", "none"),
        ("--base-depth", "--baseDepth"),
        ("--temp-dir", "--tempDir"),
        ("--estimate-memory", "none"),
    ];
    for (ours, theirs) in expected {
        let (_, text) = entries
            .iter()
            .find(|(name, _)| name == ours)
            .unwrap_or_else(|| panic!("{ours} is missing from --help: {names:?}"));
        let equivalent = text.split("PoissonRecon:").nth(1).unwrap_or_default();
        assert!(
            equivalent.trim_start().starts_with(theirs)
                || equivalent.contains(&format!(" {theirs}")),
            "{ours} should name PoissonRecon's {theirs}: {text}"
        );
    }
    assert_eq!(
        names.len(),
        expected.len() + 2,
        "an option was added or removed: give it a PoissonRecon equivalent here: {names:?}"
    );
}

/// The kitten's positions alone, as a binary PLY with `x y z` only (a scanner's export).
fn kitten_without_normals(dir: &Path) -> PathBuf {
    let cloud = psr::ply::read_point_cloud(&kitten()).unwrap();
    positions_ply(&dir.join("kitten_xyz.ply"), &cloud.positions, None)
}

/// Writes `positions` as a binary PLY with `x y z` and, if given, a second float triple per
/// vertex under the given property names (e.g. sensor positions); returns `path`.
fn positions_ply(
    path: &Path,
    positions: &[[f32; 3]],
    extra: Option<([&str; 3], &[[f32; 3]])>,
) -> PathBuf {
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\n",
        positions.len()
    );
    for name in extra.iter().flat_map(|(names, _)| names) {
        header.push_str(&format!("property float {name}\n"));
    }
    header.push_str("end_header\n");
    let mut bytes = header.into_bytes();
    for (i, p) in positions.iter().enumerate() {
        let more = extra.map(|(_, values)| values[i]);
        for c in p.iter().chain(more.iter().flatten()) {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    std::fs::write(path, bytes).unwrap();
    path.to_path_buf()
}

/// Six times the signed volume of a mesh: positive when its triangles face outward.
fn signed_volume6(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| positions[v as usize].map(f64::from));
            a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0])
        })
        .sum()
}

/// Reconstructs `input` at depth 6 with the options `extra` into `dir`/mesh.ply and returns six
/// times the mesh's signed volume.
fn volume6_at_depth_6(input: &Path, dir: &Path, extra: &[&str]) -> f64 {
    let output = dir.join("mesh.ply");
    let mut args = vec!["--depth", "6", "--quiet"];
    args.extend_from_slice(extra);
    let out = psr_on(input, &output, &args);
    assert!(out.status.success(), "{extra:?}: {}", stderr(&out));
    let (positions, triangles) = psr::ply::read_mesh(&output).unwrap();
    signed_volume6(&positions, &triangles)
}

/// Proves: a cloud without normals is reconstructed (normals estimated and oriented by
/// propagation), closed and facing outward, enclosing within 5% of the volume that the given
/// normals give.
#[test]
fn a_cloud_without_normals_is_reconstructed_facing_outward() {
    let dir = scratch("no-normals");
    let bare = kitten_without_normals(&dir);
    let from_bare = dir.join("estimated.ply");
    let from_given = dir.join("given.ply");
    for (input, output) in [(&bare, &from_bare), (&kitten(), &from_given)] {
        let out = psr_on(input, output, &["--depth", "6", "--quiet"]);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let (positions, triangles) = psr::ply::read_mesh(&from_bare).unwrap();
    let mut edges = std::collections::HashMap::new();
    for t in &triangles {
        for k in 0..3 {
            *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    assert!(
        edges
            .iter()
            .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1)),
        "every directed edge once, its reverse once: closed and consistently oriented"
    );
    let estimated = signed_volume6(&positions, &triangles);
    let (positions, triangles) = psr::ply::read_mesh(&from_given).unwrap();
    let given = signed_volume6(&positions, &triangles);
    assert!(estimated > 0.0, "the mesh faces inward: {estimated}");
    assert!(
        (estimated / given - 1.0).abs() < 0.05,
        "volume {estimated} from estimated normals vs {given} from the given ones"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: --orientation reconstruction (normals read off the reconstruction, repeated
/// --reconstruction-iterations times) gives the kitten's points alone a closed mesh facing
/// outward, within 5% of the volume that the given normals give; the file's normals re-oriented
/// by it (--normals reorient) give that volume too.
#[test]
fn reconstruction_orientation_faces_outward() {
    let dir = scratch("reconstruction-orientation");
    let bare = kitten_without_normals(&dir);
    let volume = |input: &Path, extra: &[&str]| volume6_at_depth_6(input, &dir, extra);
    let given = volume(&kitten(), &[]);
    let options = [
        "--orientation",
        "reconstruction",
        "--reconstruction-iterations",
        "8",
    ];
    let estimated = volume(&bare, &options);
    assert!(
        estimated > 0.0 && (estimated / given - 1.0).abs() < 0.05,
        "volume {estimated} from the reconstruction's normals vs {given} from the given ones"
    );
    let mut reoriented = vec!["--normals", "reorient"];
    reoriented.extend_from_slice(&options);
    let again = volume(&kitten(), &reoriented);
    assert!(
        (again / given - 1.0).abs() < 0.05,
        "volume {again} re-oriented vs {given}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn normal_options_that_cannot_be_honoured_are_usage_errors() {
    let dir = scratch("normal-options");
    let bare = kitten_without_normals(&dir);
    let out_path = dir.join("mesh.ply");
    for (input, extra, wanted) in [
        (&bare, &["--normals", "reorient"][..], "--normals estimate"),
        (&bare, &["--orientation", "viewpoint"][..], "--viewpoint"),
        (
            &bare,
            &["--orientation", "sensors"][..],
            "sensor_x sensor_y sensor_z",
        ),
        (
            &kitten(),
            &["--orientation", "sensors"][..],
            "vp_x vp_y vp_z",
        ),
        (
            &bare,
            &["--orientation", "sensors", "--viewpoint", "0,0,1"][..],
            "--viewpoint",
        ),
        (
            &kitten(),
            &["--normals", "estimate", "--neighbors", "0"][..],
            "--neighbors",
        ),
        (
            &bare,
            &["--orientation", "reconstruction", "--viewpoint", "0,0,1"][..],
            "--viewpoint",
        ),
        (
            &bare,
            &[
                "--orientation",
                "reconstruction",
                "--reconstruction-iterations",
                "0",
            ][..],
            "--reconstruction-iterations",
        ),
    ] {
        let mut args = vec!["--depth", "4"];
        args.extend_from_slice(extra);
        let out = psr_on(input, &out_path, &args);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {}", stderr(&out));
        assert!(stderr(&out).contains(wanted), "{extra:?}: {}", stderr(&out));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: --viewpoint orients every estimated normal towards the given point (here far above
/// the kitten, so the top faces up) and the reconstruction succeeds; a viewpoint whose first
/// coordinate is negative is a value, not an option.
#[test]
fn a_viewpoint_orients_the_normals() {
    let dir = scratch("viewpoint");
    let bare = kitten_without_normals(&dir);
    for viewpoint in ["0,0,1000", "-0.5,0,1000"] {
        let out_path = dir.join("mesh.ply");
        let out = psr_on(
            &bare,
            &out_path,
            &["--depth", "5", "--viewpoint", viewpoint, "--quiet"],
        );
        assert!(out.status.success(), "{viewpoint}: {}", stderr(&out));
        assert!(out_path.exists());
        std::fs::remove_file(&out_path).unwrap();
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: --orientation sensors reads each point's sensor from the file and turns its
/// estimated normal to face it. The kitten scanned from six far positions along the axes, each
/// point by the one its true normal faces most: the mesh faces outward with the volume the given
/// normals give. Each point given the opposite sensor instead (under PCL's vp_x vp_y vp_z
/// names): every normal flips and the mesh is inside out.
#[test]
fn sensors_in_the_file_orient_the_normals() {
    let dir = scratch("sensors");
    let cloud = psr::ply::read_point_cloud(&kitten()).unwrap();
    let (mut low, mut high) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in &cloud.positions {
        for k in 0..3 {
            low[k] = low[k].min(p[k]);
            high[k] = high[k].max(p[k]);
        }
    }
    let far = 1000.0 * (0..3).map(|k| high[k] - low[k]).fold(0.0, f32::max);
    let sensor_of = |n: &[f32; 3], towards: f32| {
        let axis = (0..3)
            .max_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
            .unwrap();
        let mut s: [f32; 3] = std::array::from_fn(|k| 0.5 * (low[k] + high[k]));
        s[axis] += towards * far * n[axis].signum();
        s
    };
    let seen: Vec<[f32; 3]> = cloud.normals.iter().map(|n| sensor_of(n, 1.0)).collect();
    let behind: Vec<[f32; 3]> = cloud.normals.iter().map(|n| sensor_of(n, -1.0)).collect();
    let scanned = positions_ply(
        &dir.join("scanned.ply"),
        &cloud.positions,
        Some((psr::ply::SENSOR_PROPERTIES[0], &seen)),
    );
    let reversed = positions_ply(
        &dir.join("reversed.ply"),
        &cloud.positions,
        Some((["vp_x", "vp_y", "vp_z"], &behind)),
    );
    let mut volumes = Vec::new();
    for (input, extra) in [
        (&kitten(), &[][..]),
        (&scanned, &["--orientation", "sensors"][..]),
        (&reversed, &["--orientation", "sensors"][..]),
    ] {
        volumes.push(volume6_at_depth_6(input, &dir, extra));
    }
    let [given, scanned, reversed] = volumes[..] else {
        unreachable!()
    };
    assert!(
        (scanned / given - 1.0).abs() < 0.05,
        "volume {scanned} from sensor-oriented normals vs {given} from the given ones"
    );
    assert!(
        (reversed / given + 1.0).abs() < 0.05,
        "volume {reversed} with every sensor behind its point: should be minus {given}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The upper half (z > 0) of the kitten, with its normals, as a binary PLY: a scan with a
/// missing side, whose reconstruction closes the bottom with invented surface.
fn half_kitten(dir: &Path) -> PathBuf {
    let cloud = psr::ply::read_point_cloud(&kitten()).unwrap();
    let kept: Vec<usize> = (0..cloud.positions.len())
        .filter(|&i| cloud.positions[i][2] > 0.0)
        .collect();
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
         property float nz\nend_header\n",
        kept.len()
    )
    .into_bytes();
    for &i in &kept {
        for c in cloud.positions[i].iter().chain(&cloud.normals[i]) {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let path = dir.join("half_kitten.ply");
    std::fs::write(&path, bytes).unwrap();
    path
}

/// How many times each directed edge of a mesh is used.
fn directed_edges(triangles: &[[u32; 3]]) -> std::collections::HashMap<(u32, u32), u32> {
    let mut edges = std::collections::HashMap::new();
    for t in triangles {
        for k in 0..3 {
            *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    edges
}

/// Proves: without a --trim option the output is the closed, untrimmed mesh; --trim alone cuts
/// it back (fewer triangles, a boundary, every directed edge still used once at most, the
/// summary saying where it cut); the other thresholds and the piece rules run too.
#[test]
fn trimming_is_off_by_default_and_one_flag_cuts_the_surface_back() {
    let dir = scratch("trim");
    let input = half_kitten(&dir);
    let untrimmed = dir.join("untrimmed.ply");
    let out = psr_on(&input, &untrimmed, &["--depth", "6"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!stderr(&out).contains("trimmed"), "{}", stderr(&out));
    let (_, whole) = psr::ply::read_mesh(&untrimmed).unwrap();
    let edges = directed_edges(&whole);
    assert!(
        edges
            .iter()
            .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1)),
        "the default output is closed"
    );
    let trimmed = dir.join("trimmed.ply");
    let out = psr_on(&input, &trimmed, &["--depth", "6", "--trim"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("trimmed at density"),
        "{}",
        stderr(&out)
    );
    let (_, cut) = psr::ply::read_mesh(&trimmed).unwrap();
    assert!(
        cut.len() < whole.len() * 3 / 4,
        "{} of {}",
        cut.len(),
        whole.len()
    );
    let edges = directed_edges(&cut);
    assert!(
        edges.values().all(|&n| n == 1),
        "an edge used twice the same way"
    );
    assert!(
        edges.keys().any(|&(a, b)| !edges.contains_key(&(b, a))),
        "the trimmed mesh has a boundary"
    );
    for extra in [
        &["--trim-depth", "4.5"][..],
        &["--trim-density", "1"][..],
        &["--trim-quantile", "0.5", "--min-piece-area", "0.01"][..],
        &["--trim", "--min-piece-triangles", "10", "--verbose"][..],
    ] {
        let mut args = vec!["--depth", "5"];
        args.extend_from_slice(extra);
        let out = psr_on(&input, &trimmed, &args);
        assert!(out.status.success(), "{extra:?}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("trimmed at density"),
            "{extra:?}: {}",
            stderr(&out)
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: trimming options that cannot be honoured are usage errors naming the option, before
/// any reconstruction: two thresholds at once, a piece rule without a threshold, values out of
/// range.
#[test]
fn trimming_options_that_cannot_be_honoured_are_usage_errors() {
    let dir = scratch("trim-options");
    let out_path = dir.join("mesh.ply");
    for (extra, wanted) in [
        (&["--trim", "--trim-depth", "7"][..], "--trim-depth"),
        (&["--min-piece-area", "0.1"][..], "--trim"),
        (&["--min-piece-triangles", "5"][..], "--trim"),
        (&["--trim-quantile", "1.5"][..], "--trim-quantile"),
        (&["--trim-density", "-1"][..], "--trim-density"),
        (&["--trim-depth", "40"][..], "--trim-depth"),
        (&["--trim", "--min-piece-area", "2"][..], "--min-piece-area"),
    ] {
        let mut args = vec!["--depth", "4"];
        args.extend_from_slice(extra);
        let out = psr_on(&kitten(), &out_path, &args);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {}", stderr(&out));
        assert!(stderr(&out).contains(wanted), "{extra:?}: {}", stderr(&out));
        assert!(!out_path.exists(), "{extra:?}: written anyway");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The kitten with a colour per point (by height, as ushort) and two extra properties, one of
/// them an integer; returns the path and the colours as 0..1.
fn coloured_kitten(dir: &Path) -> (PathBuf, Vec<[f32; 3]>) {
    let cloud = psr::ply::read_point_cloud(&kitten()).unwrap();
    let (lo, hi) = cloud
        .positions
        .iter()
        .fold((f32::MAX, f32::MIN), |(lo, hi), p| {
            (lo.min(p[2]), hi.max(p[2]))
        });
    let colors: Vec<[f32; 3]> = cloud
        .positions
        .iter()
        .map(|p| {
            let t = ((p[2] - lo) / (hi - lo) * 65535.0).round() / 65535.0;
            [t, 0.5, 1.0 - t]
        })
        .collect();
    let mut points = psr::ply::PlyPoints::default();
    points.positions = cloud.positions.clone();
    points.normals = cloud.normals.clone();
    points.colors = Some(psr::Colors::Rgb(colors.clone()));
    points.color_type = psr::ply::ColorType::U16;
    points.channels = vec![
        psr::Channel::new("intensity", vec![0.75; cloud.len()]),
        psr::Channel::new("label", vec![3.0; cloud.len()]),
    ];
    let path = dir.join("kitten_rgb.ply");
    psr::ply::write_point_cloud(&path, &points, psr::ply::PlyFormat::BinaryLittleEndian).unwrap();
    (path, colors)
}

/// The header of a PLY file.
fn ply_header(path: &Path) -> String {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap();
    String::from_utf8(bytes[..end].to_vec()).unwrap()
}

/// Proves: by default the input's colours come back in its type (here ushort) and its other
/// vertex properties as floats, with the values carried (constants stay constant, colours
/// follow the height); --no-attributes drops them; --vertex-normals writes unit nx ny nz.
#[test]
fn colours_and_other_properties_are_carried_onto_the_mesh() {
    let dir = scratch("attributes");
    let (input, _) = coloured_kitten(&dir);
    let carried = dir.join("carried.ply");
    let out = psr_on(
        &input,
        &carried,
        &["--depth", "5", "--vertex-normals", "--verbose"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("carrying colors (3 components) and channels [intensity, label]"),
        "{}",
        stderr(&out)
    );
    let header = ply_header(&carried);
    for line in [
        "property float nx",
        "property float value",
        "property ushort red",
        "property ushort blue",
        "property float intensity",
        "property float label",
    ] {
        assert!(header.contains(line), "{line} missing from\n{header}");
    }
    // The mesh's vertices read back as a point cloud (they have nx ny nz).
    let mesh = psr::ply::read_point_cloud(&carried).unwrap();
    assert_eq!(mesh.color_type, psr::ply::ColorType::U16);
    let names: Vec<&str> = mesh.channels.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["intensity", "label"]);
    assert!(mesh.channels[0]
        .values
        .iter()
        .all(|&v| (v - 0.75).abs() < 1e-6));
    assert!(mesh.channels[1]
        .values
        .iter()
        .all(|&v| (v - 3.0).abs() < 1e-5));
    let Some(psr::Colors::Rgb(colors)) = &mesh.colors else {
        panic!("RGB colours expected")
    };
    for c in colors {
        assert!(
            (c[1] - 0.5).abs() < 1e-4 && (c[0] + c[2] - 1.0).abs() < 1e-3,
            "{c:?}"
        );
    }
    let (lo, hi) = colors
        .iter()
        .fold((1.0f32, 0.0f32), |(lo, hi), c| (lo.min(c[0]), hi.max(c[0])));
    assert!(
        lo < 0.2 && hi > 0.8,
        "the height's colour ramp comes through: {lo} {hi}"
    );
    for n in &mesh.normals {
        assert!((n.iter().map(|c| c * c).sum::<f32>().sqrt() - 1.0).abs() < 1e-4);
    }

    let dropped = dir.join("dropped.ply");
    let out = psr_on(
        &input,
        &dropped,
        &["--depth", "5", "--no-attributes", "--quiet"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let header = ply_header(&dropped);
    assert!(
        !header.contains("red") && !header.contains("intensity") && !header.contains("nx"),
        "{header}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs psr on `input` writing `output` with `extra`, and asserts that it succeeded.
fn reconstruct(input: &Path, output: &Path, extra: &[&str]) {
    let out = psr_on(input, output, extra);
    assert!(
        out.status.success(),
        "psr --in {} --out {} {extra:?}: {}",
        input.display(),
        output.display(),
        stderr(&out)
    );
}

/// Proves: the kitten as PoissonRecon's ASCII points (x y z nx ny nz, .npts) and as positions
/// alone (x y z, .xyz: normals estimated) gives the same mesh as the same points in PLY, to
/// the bit (the text holds each float exactly).
#[test]
fn ascii_points_with_and_without_normals_are_read_like_ply() {
    let dir = scratch("ascii-in");
    let cloud = psr::ply::read_point_cloud(&kitten()).unwrap();
    let with_normals = dir.join("kitten.npts");
    psr::npts::write_ascii(&with_normals, &cloud).unwrap();
    let first = std::fs::read_to_string(&with_normals).unwrap();
    assert_eq!(first.lines().next().unwrap().split(' ').count(), 6);
    let mut positions_only = psr::ply::PlyPoints::default();
    positions_only.positions = cloud.positions.clone();
    let without_normals = dir.join("kitten.XYZ");
    psr::npts::write_ascii(&without_normals, &positions_only).unwrap();
    let bare_ply = kitten_without_normals(&dir);

    for (ascii, ply, name) in [
        (&with_normals, kitten(), "normals"),
        (&without_normals, bare_ply, "estimated"),
    ] {
        let from_ascii = dir.join(format!("{name}-ascii.ply"));
        let from_ply = dir.join(format!("{name}-ply.ply"));
        reconstruct(ascii, &from_ascii, &["--depth", "5", "--quiet"]);
        reconstruct(&ply, &from_ply, &["--depth", "5", "--quiet"]);
        let mesh = psr::ply::read_mesh(&from_ascii).unwrap();
        assert!(mesh.1.len() > 1000, "{name}: {} triangles", mesh.1.len());
        assert_eq!(mesh, psr::ply::read_mesh(&from_ply).unwrap(), "{name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: an ASCII file whose lines disagree is a run error naming the file and the line, and
/// --colors on an ASCII file without colours is a usage error.
#[test]
fn bad_ascii_points_are_refused_naming_the_line() {
    let dir = scratch("ascii-bad");
    let input = dir.join("cloud.npts");
    std::fs::write(
        &input,
        "# x y z nx ny nz\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 1\n",
    )
    .unwrap();
    let out_path = dir.join("mesh.ply");
    let out = psr_on(&input, &out_path, &["--depth", "4"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("cloud.npts: line 4: 5 numbers, but line 2 (the first point) has 6"),
        "{}",
        stderr(&out)
    );
    std::fs::write(&input, "0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 1 0\n").unwrap();
    let out = psr_on(&input, &out_path, &["--depth", "4", "--colors"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--colors"), "{}", stderr(&out));
    assert!(!out_path.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: the kitten as .bnpts gives the same mesh as the PLY; with colours (--colors, 27-byte
/// records) the colours reach the mesh, and the wrong layout is refused with a hint.
#[test]
fn bnpts_points_are_read_with_and_without_colours() {
    let dir = scratch("bnpts");
    let cloud = psr::ply::read_point_cloud(&kitten()).unwrap();
    let plain = dir.join("kitten.bnpts");
    psr::npts::write_binary(&plain, &cloud).unwrap();
    assert_eq!(
        std::fs::metadata(&plain).unwrap().len(),
        24 * cloud.len() as u64
    );
    let from_bnpts = dir.join("bnpts.ply");
    let from_ply = dir.join("ply.ply");
    reconstruct(&plain, &from_bnpts, &["--depth", "5", "--quiet"]);
    reconstruct(&kitten(), &from_ply, &["--depth", "5", "--quiet"]);
    assert_eq!(
        psr::ply::read_mesh(&from_bnpts).unwrap(),
        psr::ply::read_mesh(&from_ply).unwrap()
    );

    let (coloured_ply, _) = coloured_kitten(&dir);
    let mut coloured = psr::ply::read_point_cloud(&coloured_ply).unwrap();
    coloured.channels.clear();
    let rgb = dir.join("kitten_rgb.bnpts");
    psr::npts::write_binary(&rgb, &coloured).unwrap();
    let mesh_path = dir.join("rgb.ply");
    reconstruct(&rgb, &mesh_path, &["--depth", "5", "--quiet", "--colors"]);
    let header = ply_header(&mesh_path);
    assert!(header.contains("property uchar red"), "{header}");
    let mesh = psr::ply::read_points(&mesh_path).unwrap();
    let Some(psr::Colors::Rgb(colors)) = &mesh.colors else {
        panic!("RGB colours expected")
    };
    assert!(
        colors.iter().all(|c| (c[1] - 0.5).abs() < 0.01),
        "green is 128/255 everywhere"
    );

    // 27-byte records read as 24-byte ones: 5,210 × 27 is not a multiple of 24.
    let out = psr_on(&rgb, &dir.join("wrong.ply"), &["--depth", "4"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("not a whole number of 24-byte records")
            && stderr(&out).contains("27 with --colors"),
        "{}",
        stderr(&out)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: --ascii writes ASCII PLY holding the same mesh as the binary output (positions to
/// the bit, density and normals as properties).
#[test]
fn ascii_ply_output_holds_the_binary_mesh() {
    let dir = scratch("ascii-out");
    let binary = dir.join("binary.ply");
    let ascii = dir.join("ascii.ply");
    let args = ["--depth", "5", "--quiet", "--vertex-normals"];
    reconstruct(&kitten(), &binary, &args);
    reconstruct(&kitten(), &ascii, &[&args[..], &["--ascii"]].concat());
    let header = ply_header(&ascii);
    assert!(header.starts_with("ply\nformat ascii 1.0\n"), "{header}");
    assert!(
        header.contains("property float value\n")
            && header.contains("property list uchar int vertex_indices"),
        "{header}"
    );
    assert_eq!(
        psr::ply::read_mesh(&ascii).unwrap(),
        psr::ply::read_mesh(&binary).unwrap()
    );
    assert_eq!(
        psr::ply::read_point_cloud(&ascii).unwrap(),
        psr::ply::read_point_cloud(&binary).unwrap(),
        "the vertices with their normals and density"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: an .obj output holds the PLY output's mesh (the same vertices and triangles,
/// 1-based), with a vn per vertex under --vertex-normals and `v x y z r g b` when coloured;
/// --verbose says what OBJ cannot hold.
#[test]
fn obj_output_holds_the_ply_mesh() {
    let dir = scratch("obj-out");
    let (input, _) = coloured_kitten(&dir);
    let ply = dir.join("mesh.ply");
    let obj = dir.join("mesh.OBJ");
    reconstruct(
        &input,
        &ply,
        &["--depth", "5", "--quiet", "--vertex-normals"],
    );
    let out = psr_on(
        &input,
        &obj,
        &["--depth", "5", "--vertex-normals", "--verbose"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("OBJ has no place for the density (value), intensity, label"),
        "{}",
        stderr(&out)
    );
    let (positions, triangles) = psr::obj::read_mesh(&obj).unwrap();
    assert_eq!(
        (positions, triangles),
        psr::ply::read_mesh(&ply).unwrap(),
        "the same mesh"
    );
    let text = std::fs::read_to_string(&obj).unwrap();
    let vertices: Vec<&str> = text.lines().filter(|l| l.starts_with("v ")).collect();
    let normals = text.lines().filter(|l| l.starts_with("vn ")).count();
    let faces: Vec<&str> = text.lines().filter(|l| l.starts_with("f ")).collect();
    assert_eq!(normals, vertices.len());
    assert!(
        vertices.iter().all(|v| v.split(' ').count() == 7),
        "v x y z r g b"
    );
    let indices: Vec<u64> = faces
        .iter()
        .flat_map(|f| f.split(' ').skip(1))
        .map(|corner| {
            let (v, n) = corner.split_once("//").expect("v//n corners");
            assert_eq!(v, n);
            v.parse().unwrap()
        })
        .collect();
    assert_eq!(indices.iter().min(), Some(&1), "1-based");
    assert_eq!(indices.iter().max(), Some(&(vertices.len() as u64)));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Asserts that `psr --depth 4 args` on `input` is a usage error (exit 2) whose message contains
/// `needle`.
fn assert_usage_error(input: &Path, dir: &Path, args: &[&str], needle: &str) {
    let mut all = vec!["--depth", "4"];
    all.extend(args.iter().copied());
    let out = psr_on(input, &dir.join("bad.ply"), &all);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
    assert!(stderr(&out).contains(needle), "{args:?}: {}", stderr(&out));
}

/// Proves: --grid writes χ on a grid as a NumPy .npy (version 1.0 header, little-endian float32,
/// shape (N, N, N), data aligned to 64 bytes) whose values are the library's
/// `ImplicitFunction::sample_grid` bit for bit, and as .raw the same values without a header;
/// --grid-resolution out of range and other extensions are usage errors.
#[test]
fn grid_writes_chi_as_npy_and_raw() {
    let dir = scratch("grid");
    let kitten = kitten();
    let mesh = dir.join("mesh.ply");
    let npy = dir.join("chi.npy");
    let out = psr_on(
        &kitten,
        &mesh,
        &[
            "--depth",
            "4",
            "--grid",
            npy.to_str().unwrap(),
            "--grid-resolution",
            "10",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("grid 10x10x10"), "{}", stderr(&out));
    let bytes = std::fs::read(&npy).unwrap();
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let start = 10 + header_len;
    assert_eq!(start % 64, 0);
    let header = std::str::from_utf8(&bytes[10..start]).unwrap();
    assert!(header.ends_with('\n'), "{header:?}");
    assert!(
        header.starts_with("{'descr': '<f4', 'fortran_order': False, 'shape': (10, 10, 10), }"),
        "{header:?}"
    );
    assert_eq!(bytes.len() - start, 4 * 1000);
    let values: Vec<f32> = bytes[start..]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    // The library's grid for the same points and parameters, bit for bit.
    let cloud = psr::ply::read_point_cloud(&kitten).unwrap();
    let points = psr::PointSet::from_slices(&cloud.positions, &cloud.normals).unwrap();
    let params = psr::Params::default().with_depth(4);
    let (_, chi) = psr::reconstruct_with_implicit(&points, &params).unwrap();
    let expected = chi.sample_grid(10).unwrap();
    assert!(values
        .iter()
        .zip(&expected)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    // Inside and outside: χ − γ changes sign on the grid.
    let gamma = chi.isovalue() as f32;
    assert!(values.iter().any(|&v| v < gamma) && values.iter().any(|&v| v > gamma));

    // .raw: the same values, no header; the default resolution is 2^depth.
    let raw = dir.join("chi.RAW");
    let out = psr_on(
        &kitten,
        &mesh,
        &["--depth", "4", "--grid", raw.to_str().unwrap()],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(std::fs::read(&raw).unwrap().len(), 4 * 16 * 16 * 16);

    for (args, needle) in [
        (
            vec!["--grid", "chi.txt"],
            "psr writes grids to .npy or .raw files",
        ),
        (
            vec!["--grid", npy.to_str().unwrap(), "--grid-resolution", "0"],
            "--grid-resolution",
        ),
        (
            vec!["--grid", npy.to_str().unwrap(), "--grid-resolution", "5000"],
            "--grid-resolution",
        ),
        (vec!["--grid-resolution", "8"], "--grid"),
    ] {
        assert_usage_error(&kitten, &dir, &args, needle);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: --grid-box samples χ over the given box instead of the cube, the library's
/// `ImplicitFunction::sample_box` bit for bit (a flat box too: a slice); a box with five
/// numbers, a non-finite one or its corners the wrong way round, and --grid-box without --grid,
/// are usage errors.
#[test]
fn grid_box_samples_chi_over_a_box() {
    let dir = scratch("grid-box");
    let kitten = kitten();
    let mesh = dir.join("mesh.ply");
    let cloud = psr::ply::read_point_cloud(&kitten).unwrap();
    let points = psr::PointSet::from_slices(&cloud.positions, &cloud.normals).unwrap();
    let (_, chi) =
        psr::reconstruct_with_implicit(&points, &psr::Params::default().with_depth(4)).unwrap();
    let (origin, size) = chi.cube();
    let lo = origin.map(|o| o + 0.25 * size);
    let hi = origin.map(|o| o + 0.6 * size);
    for (label, min, max) in [("box", lo, hi), ("slice", lo, [hi[0], hi[1], lo[2]])] {
        let raw = dir.join(format!("{label}.raw"));
        let corners = format!(
            "{},{},{},{},{},{}",
            min[0], min[1], min[2], max[0], max[1], max[2]
        );
        let out = psr_on(
            &kitten,
            &mesh,
            &[
                "--depth",
                "4",
                "--grid",
                raw.to_str().unwrap(),
                "--grid-resolution",
                "6",
                "--grid-box",
                &corners,
            ],
        );
        assert!(out.status.success(), "{label}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("over the box from"),
            "{}",
            stderr(&out)
        );
        let values: Vec<f32> = std::fs::read(&raw)
            .unwrap()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let expected = chi.sample_box(min, max, 6).unwrap();
        assert_eq!(values.len(), 216, "{label}");
        assert!(
            values
                .iter()
                .zip(&expected)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{label}"
        );
    }
    let npy = dir.join("chi.npy");
    for (args, needle) in [
        (
            vec!["--grid", npy.to_str().unwrap(), "--grid-box", "0,0,0,1,1"],
            "six finite numbers",
        ),
        (
            vec![
                "--grid",
                npy.to_str().unwrap(),
                "--grid-box",
                "0,0,0,1,nan,1",
            ],
            "six finite numbers",
        ),
        (
            vec!["--grid", npy.to_str().unwrap(), "--grid-box", "0,0,1,1,1,0"],
            "above the upper one",
        ),
        (vec!["--grid-box", "0,0,0,1,1,1"], "--grid"),
    ] {
        assert_usage_error(&kitten, &dir, &args, needle);
    }
    assert!(!npy.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Writes the kitten's points as binary PLY with `double` x y z, each shifted by `shift`.
fn kitten_in_double(path: &Path, shift: [f64; 3]) {
    let cloud = psr::ply::read_points(&kitten()).unwrap();
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\n\
         property double y\nproperty double z\nproperty float nx\nproperty float ny\n\
         property float nz\nend_header\n",
        cloud.positions.len()
    )
    .into_bytes();
    for (p, n) in cloud.positions.iter().zip(&cloud.normals) {
        for a in 0..3 {
            bytes.extend_from_slice(&(p[a] as f64 + shift[a]).to_le_bytes());
        }
        for c in n {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    std::fs::write(path, bytes).unwrap();
}

/// Writes the kitten's points as ASCII `x y z nx ny nz` lines, each position shifted by `shift`
/// and written with every digit its `f64` needs.
fn kitten_in_ascii(path: &Path, shift: [f64; 3]) {
    let cloud = psr::ply::read_points(&kitten()).unwrap();
    let mut text = String::new();
    for (p, n) in cloud.positions.iter().zip(&cloud.normals) {
        let p = [0, 1, 2].map(|a| p[a] as f64 + shift[a]);
        text.push_str(&format!(
            "{} {} {} {} {} {}\n",
            p[0], p[1], p[2], n[0], n[1], n[2]
        ));
    }
    std::fs::write(path, text).unwrap();
}

/// The vertices of a binary mesh PLY that psr wrote with `double` x y z (then a float density).
fn double_vertices(path: &Path) -> Vec<[f64; 3]> {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]).into_owned();
    assert!(header.contains("property double x"), "{header}");
    assert!(header.contains("property float value"), "{header}");
    let n: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .unwrap()
        .parse()
        .unwrap();
    (0..n)
        .map(|i| {
            let at = end + i * 28;
            [0, 1, 2].map(|a| {
                let b = &bytes[at + 8 * a..at + 8 * a + 8];
                f64::from_le_bytes(b.try_into().unwrap())
            })
        })
        .collect()
}

/// Proves: a PLY with double x y z 10^6 away is read and reconstructed in double and written
/// with double x y z, giving the mesh of the same points near 0 shifted (1e-6 of the diagonal,
/// vertices on the isosurface); so does an ASCII `.xyz` of those points (its digits say more
/// than f32 holds); --transform with that shift as a translation gives it too from the float
/// file; a singular or malformed transform is a usage error.
#[test]
fn double_inputs_and_transforms_keep_far_coordinates() {
    let dir = scratch("double");
    let shift = [1e6, -2e6, 3e5];
    let (near, far) = (dir.join("near.ply"), dir.join("far.ply"));
    kitten_in_double(&near, [0.0; 3]);
    kitten_in_double(&far, shift);
    let far_ascii = dir.join("far.xyz");
    kitten_in_ascii(&far_ascii, shift);
    let flags = ["--depth", "7", "--vertices", "on-isosurface", "-q"];
    let run = |input: &Path, output: &Path, extra: &[&str]| {
        let mut all = flags.to_vec();
        all.extend_from_slice(extra);
        let out = psr_on(input, output, &all);
        assert!(out.status.success(), "{}", stderr(&out));
        double_vertices(output)
    };
    let want = run(&near, &dir.join("near_mesh.ply"), &[]);
    let lo = want
        .iter()
        .fold([f64::INFINITY; 3], |m, p| [0, 1, 2].map(|a| m[a].min(p[a])));
    let hi = want.iter().fold([f64::NEG_INFINITY; 3], |m, p| {
        [0, 1, 2].map(|a| m[a].max(p[a]))
    });
    let diagonal = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
    let transform = dir.join("shift.txt");
    std::fs::write(&transform, "1 0 0 1e6\n0 1 0 -2e6\n0 0 1 3e5\n0 0 0 1\n").unwrap();
    let transform_arg = transform.to_str().unwrap();
    for (label, got) in [
        ("double input", run(&far, &dir.join("far_mesh.ply"), &[])),
        (
            "ASCII input",
            run(&far_ascii, &dir.join("far_ascii_mesh.ply"), &[]),
        ),
        (
            "--transform",
            run(
                &kitten(),
                &dir.join("moved_mesh.ply"),
                &["--transform", transform_arg],
            ),
        ),
    ] {
        assert_eq!(got.len(), want.len(), "{label}");
        let worst = got
            .iter()
            .zip(&want)
            .map(|(p, q)| {
                (0..3)
                    .map(|a| (p[a] - shift[a] - q[a]).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        assert!(worst < 1e-6 * diagonal, "{label}: {worst} of {diagonal}");
    }
    std::fs::write(&transform, "1 0 0 0\n0 0 0 0\n0 0 1 0\n0 0 0 1\n").unwrap();
    let out = psr_on(
        &kitten(),
        &dir.join("x.ply"),
        &["--transform", transform_arg],
    );
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("singular"), "{}", stderr(&out));
    std::fs::write(&transform, "1 0 0 0 1 0").unwrap();
    let out = psr_on(
        &kitten(),
        &dir.join("x.ply"),
        &["--transform", transform_arg],
    );
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("expected 16"), "{}", stderr(&out));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves: --min-component-samples reaches the reconstruction. The kitten with a pebble of 400
/// samples beside it keeps the pebble by default (nothing left out, as --verbose reports) and
/// loses it when more samples than it has are asked for; a value that is not a count is a usage
/// error.
#[test]
fn min_component_samples_leaves_out_pieces_with_fewer_samples() {
    let dir = scratch("min_component_samples");
    let mut cloud = psr::ply::read_point_cloud(&kitten()).unwrap();
    let (lo, hi) = cloud
        .positions
        .iter()
        .fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
            (
                std::array::from_fn(|a| lo[a].min(p[a])),
                std::array::from_fn(|a| hi[a].max(p[a])),
            )
        });
    let side = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f32::max);
    let radius = 0.03 * side;
    let centre = [
        hi[0] + 0.1 * side,
        (lo[1] + hi[1]) / 2.0,
        (lo[2] + hi[2]) / 2.0,
    ];
    // 400 points of a sphere (a Fibonacci lattice), normals outward.
    for k in 0..400 {
        let z = 1.0 - 2.0 * (k as f32 + 0.5) / 400.0;
        let r = (1.0 - z * z).sqrt();
        let phi = k as f32 * 2.399_963;
        let n = [r * phi.cos(), r * phi.sin(), z];
        cloud
            .positions
            .push(std::array::from_fn(|a| centre[a] + radius * n[a]));
        cloud.normals.push(n);
    }
    let input = dir.join("kitten_and_pebble.ply");
    psr::ply::write_point_cloud(&input, &cloud, psr::ply::PlyFormat::BinaryLittleEndian).unwrap();
    let mesh = dir.join("mesh.ply");
    let kept = psr_on(&input, &mesh, &["--depth", "7", "--verbose"]);
    assert_eq!(kept.status.code(), Some(0), "{}", stderr(&kept));
    assert!(
        stderr(&kept).contains("psr: 0 unsupported components left out"),
        "{}",
        stderr(&kept)
    );
    let strict = psr_on(
        &input,
        &mesh,
        &[
            "--depth",
            "7",
            "--verbose",
            "--min-component-samples",
            "1000",
        ],
    );
    assert_eq!(strict.status.code(), Some(0), "{}", stderr(&strict));
    assert!(
        stderr(&strict).contains("psr: 1 unsupported components left out"),
        "{}",
        stderr(&strict)
    );
    let bad = psr_on(&input, &mesh, &["--min-component-samples", "few"]);
    assert_eq!(bad.status.code(), Some(2), "{}", stderr(&bad));
    assert!(
        stderr(&bad).contains("--min-component-samples"),
        "{}",
        stderr(&bad)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves (issue 19): --max-memory takes sizes with units (and refuses a bad unit as a usage
/// error, exit 2); a limit far too small stops the run with exit status 3, a message naming
/// the limit and the option, and no output file; a sufficient limit writes the same mesh as no
/// limit, byte for byte; --estimate-memory prints a figure and writes nothing.
#[test]
fn max_memory_refuses_with_exit_3_and_estimate_memory_prints_a_figure() {
    let input = kitten();
    let dir = scratch("memory");
    let small = dir.join("small.ply");
    let out = psr_on(&input, &small, &["--depth", "5", "--max-memory", "64K"]);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    let text = stderr(&out);
    assert!(
        text.contains("memory limit of 64.00 KiB") && text.contains("--max-memory"),
        "{text}"
    );
    assert!(!small.exists(), "nothing written on failure");

    let out = psr_on(
        &input,
        &small,
        &["--depth", "5", "--max-memory", "12 parsecs"],
    );
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("unknown unit"), "{}", stderr(&out));

    let limited = dir.join("limited.ply");
    let unlimited = dir.join("unlimited.ply");
    for (path, extra) in [
        (&limited, &["--max-memory", "1.5GiB"][..]),
        (&unlimited, &["--max-memory", "0"][..]),
    ] {
        let mut args = vec!["--depth", "5"];
        args.extend_from_slice(extra);
        let out = psr_on(&input, path, &args);
        assert!(out.status.success(), "{}", stderr(&out));
    }
    assert_eq!(
        std::fs::read(&limited).unwrap(),
        std::fs::read(&unlimited).unwrap()
    );

    let estimate = dir.join("estimate.ply");
    let out = psr_on(&input, &estimate, &["--depth", "8", "--estimate-memory"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let bytes: u64 = stdout.split_whitespace().next().unwrap().parse().unwrap();
    assert!(bytes > 1 << 20 && stdout.contains("depth 8"), "{stdout}");
    assert!(!estimate.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A binary PLY of `n` oriented points on the unit sphere (a golden-angle spiral).
fn sphere_cloud(path: &Path, n: usize) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut cloud = psr::ply::PlyPoints::default();
    for i in 0..n {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - z * z).sqrt();
        let t = golden * i as f64;
        let p = [r * t.cos(), r * t.sin(), z].map(|c| c as f32);
        cloud.positions.push(p);
        cloud.normals.push(p);
    }
    psr::ply::write_point_cloud(path, &cloud, psr::ply::PlyFormat::BinaryLittleEndian).unwrap();
}

/// Proves `--out-of-core` writes a closed mesh and says how many slabs it made, leaves its
/// temporary directory empty, follows the noise when asked (saying so with --verbose), and
/// refuses the options it does not take, naming them.
#[test]
fn out_of_core_writes_the_mesh_and_refuses_the_options_it_does_not_take() {
    let dir = scratch("ooc");
    let input = dir.join("sphere.ply");
    sphere_cloud(&input, 50_000);
    let tmp = dir.join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let output = dir.join("mesh.ply");
    let out_of_core = |extra: &[&str]| {
        let mut args = vec![
            "--depth",
            "8",
            "--out-of-core",
            "--slabs",
            "3",
            "--temp-dir",
            tmp.to_str().unwrap(),
            "--verbose",
        ];
        args.extend_from_slice(extra);
        psr_on(&input, &output, &args)
    };
    // By default the screening follows the noise: the sphere's samples are exact, the noise
    // read is 0 and the screening keeps 2^8.
    let out = out_of_core(&[]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(stderr(&out).contains("3 slabs"), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(
            "screening weight scaled by 2^8.00 (the samples' noise: 0.0000e0 in input units)"
        ),
        "{}",
        stderr(&out)
    );
    let (positions, triangles) = psr::ply::read_mesh(&output).unwrap();
    // Closed: every edge in two triangles, so 3F = 2E, and a sphere: V − E + F = 2.
    assert_eq!(positions.len() * 2, triangles.len() + 4);
    assert_eq!(std::fs::read_dir(&tmp).unwrap().count(), 0);
    // Not following it: no noise estimated.
    let fixed = out_of_core(&["--screening-follows-noise", "false"]);
    assert_eq!(fixed.status.code(), Some(0), "{}", stderr(&fixed));
    assert!(
        stderr(&fixed).contains("screening weight scaled by 2^8.00\n"),
        "{}",
        stderr(&fixed)
    );
    assert_eq!(std::fs::read_dir(&tmp).unwrap().count(), 0);
    let refused = psr_on(
        &input,
        &dir.join("mesh.obj"),
        &[
            "--depth",
            "8",
            "--out-of-core",
            "--vertex-normals",
            "--no-density",
        ],
    );
    assert_eq!(refused.status.code(), Some(2), "{}", stderr(&refused));
    let message = stderr(&refused);
    assert!(
        message.contains("--vertex-normals") && message.contains("--no-density"),
        "{message}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves Ctrl-C during `--out-of-core` stops the run with exit status 130 and removes its
/// temporary directory (gigabytes for a large cloud) rather than leaving it behind.
#[test]
fn out_of_core_interrupted_removes_its_temporary_files() {
    let dir = scratch("ooc-interrupt");
    let input = dir.join("sphere.ply");
    sphere_cloud(&input, 400_000);
    let tmp = dir.join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let mut child = Command::new(PSR)
        .args([
            "--in",
            input.to_str().unwrap(),
            "--out",
            dir.join("mesh.ply").to_str().unwrap(),
            "--depth",
            "10",
            "--out-of-core",
            "--slabs",
            "4",
            "--temp-dir",
            tmp.to_str().unwrap(),
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Interrupted once the run has made its temporary directory (mid-run, whatever the speed).
    let started = std::time::Instant::now();
    while std::fs::read_dir(&tmp).unwrap().count() == 0 {
        assert!(
            started.elapsed().as_secs() < 120,
            "no temporary directory appeared"
        );
        assert!(child.try_wait().unwrap().is_none(), "psr ended early");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // SAFETY: kill sends a signal to the child process we started; no memory is involved.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{}", stderr(&out));
    assert_eq!(
        std::fs::read_dir(&tmp).unwrap().count(),
        0,
        "temporary files left"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
