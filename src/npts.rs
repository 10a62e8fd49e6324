//! PoissonRecon's raw point files, the inputs its `--in` reads besides PLY (the module is named
//! after the extensions of its examples: `.npts` for ASCII, `.bnpts` for binary).
//!
//! * **ASCII** ([`read_ascii`]): one point per line, its numbers separated by spaces or tabs,
//!   and as many on every point line as on the first:
//!   - 3: `x y z`, positions only (no normals: [`PlyPoints::normals`] is empty, for psr to
//!     estimate them as for a PLY without `nx ny nz`);
//!   - 6: `x y z nx ny nz`, PoissonRecon's layout;
//!   - 9: `x y z nx ny nz r g b` with colours from 0 to 255, PoissonRecon's layout with
//!     `--colors`.
//!
//!   Blank lines and lines starting with `#` are skipped. (PoissonRecon reads any whitespace,
//!   line ends included, as a separator, and knows no comments; psr keeps one point per line so
//!   that an error can name the line.) The numbers are read as `f64`; when some coordinate
//!   states more than `f32` holds (its nearest `f32` lies more than half a unit of its last
//!   digit away, as in georeferenced clouds: `5412345.456` is `5412345.5` in `f32`), the
//!   positions are kept in [`PlyPoints::positions_f64`] too, as a PLY's `double` ones are.
//! * **Binary `.bnpts`** ([`read_binary`]): no header and no count, only records, one per
//!   point: six little-endian `float32` `x y z nx ny nz` (24 bytes), or with colours (PoissonRecon's
//!   `--colors`) those six then `r g b` as three bytes (27 bytes). A file does not say which,
//!   so the caller does.
//!
//! Both read into [`PlyPoints`] (positions, normals, and colours scaled to 0–1 as from a PLY
//! `uchar` property), so a program treats every input alike. The writers ([`write_ascii`],
//! [`write_binary`]) write the same layouts, for conversions and tests.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Write};
use std::path::Path;

use crate::ply::{write_file, Chunk, ColorType, PlyPoints};
use crate::Colors;

/// Bytes per `.bnpts` record: six `float32`, and three colour bytes when `colors`.
pub fn binary_record_bytes(colors: bool) -> usize {
    if colors {
        27
    } else {
        24
    }
}

/// An error about the data (not the file system), with `path` in front when known.
fn invalid(path: Option<&Path>, message: String) -> io::Error {
    let message = match path {
        Some(p) => format!("{}: {message}", p.display()),
        None => message,
    };
    io::Error::new(io::ErrorKind::InvalidData, message)
}

/// Opens `path`, with its length when it is a regular file.
fn open(path: &Path) -> io::Result<(File, Option<u64>)> {
    let file = File::open(path)
        .map_err(|e| io::Error::new(e.kind(), format!("{}: cannot open: {e}", path.display())))?;
    let len = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len());
    Ok((file, len))
}

/// Reads the ASCII points file `path` (see [`read_ascii_from`]); errors name the path.
pub fn read_ascii(path: &Path) -> io::Result<PlyPoints> {
    let (file, _) = open(path)?;
    read_ascii_impl(BufReader::with_capacity(1 << 20, file), Some(path))
}

/// Reads ASCII points, one per line (the [module documentation](self) gives the layouts). A
/// line that is not numbers, a first line with another count than 3, 6 or 9, a line whose count
/// differs from the first's and a colour outside 0–255 are errors naming the line.
pub fn read_ascii_from(reader: impl BufRead) -> io::Result<PlyPoints> {
    read_ascii_impl(reader, None)
}

fn read_ascii_impl(mut reader: impl BufRead, path: Option<&Path>) -> io::Result<PlyPoints> {
    let mut points = PlyPoints::default();
    let mut colors: Vec<[f32; 3]> = Vec::new();
    // The column count of the first point line, and its line number.
    let mut layout: Option<(usize, usize)> = None;
    let mut bytes = Vec::new();
    let mut values = [0.0f64; 9];
    // Every position as read, kept when some coordinate states more than f32 holds.
    let mut exact: Vec<[f64; 3]> = Vec::new();
    let mut needs_f64 = false;
    let mut line = 0usize;
    let bad = |line: usize, what: String| invalid(path, format!("line {line}: {what}"));
    loop {
        bytes.clear();
        let read = reader
            .read_until(b'\n', &mut bytes)
            .map_err(|e| match path {
                Some(p) => io::Error::new(e.kind(), format!("{}: cannot read: {e}", p.display())),
                None => e,
            })?;
        if read == 0 {
            break;
        }
        line += 1;
        let Ok(text) = std::str::from_utf8(&bytes) else {
            return Err(bad(line, "not text (is this a binary file?)".into()));
        };
        let text = text.trim_start();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let mut count = 0;
        for word in text.split_ascii_whitespace() {
            let value: f64 = word
                .parse()
                .map_err(|_| bad(line, format!("'{word}' is not a number")))?;
            if count < 3 && !needs_f64 {
                needs_f64 = !f32_states(word, value);
            }
            if let Some(slot) = values.get_mut(count) {
                *slot = value;
            }
            count += 1;
        }
        let columns = match layout {
            Some((columns, _)) if columns == count => columns,
            Some((columns, first)) => {
                return Err(bad(
                    line,
                    format!(
                        "{count} numbers, but line {first} (the first point) has {columns}: \
                         every point has the same layout"
                    ),
                ))
            }
            None if matches!(count, 3 | 6 | 9) => {
                layout = Some((count, line));
                count
            }
            None => {
                return Err(bad(
                    line,
                    format!(
                        "{count} numbers: a point is 3 (x y z), 6 (x y z nx ny nz) or 9 \
                         (x y z nx ny nz r g b, colours 0-255) numbers on one line"
                    ),
                ))
            }
        };
        let values64 = values;
        let values = values64.map(|v| v as f32);
        points.positions.push([values[0], values[1], values[2]]);
        exact.push([0, 1, 2].map(|a| values64[a]));
        if columns >= 6 {
            points.normals.push([values[3], values[4], values[5]]);
        }
        if columns == 9 {
            let rgb = [values[6], values[7], values[8]];
            if let Some(c) = rgb.iter().find(|c| !(0.0..=255.0).contains(*c)) {
                return Err(bad(line, format!("colour component {c} is outside 0-255")));
            }
            colors.push(rgb.map(|c| (c as f64 / 255.0) as f32));
        }
    }
    if needs_f64 {
        points.positions_f64 = Some(exact);
    }
    if layout.is_some_and(|(columns, _)| columns == 9) {
        points.colors = Some(Colors::Rgb(colors));
        points.color_type = ColorType::U8;
    }
    Ok(points)
}

/// Whether `f32` holds all that the decimal `text` (parsed as `value`) states: the value is in
/// `f32`'s range and its nearest `f32` lies within half a unit of the text's last digit
/// (`0.100000001`, the nine digits C's `%.9g` writes of an `f32`; `0.1`, the shortest form
/// psr writes; `12.345678`; every integer up to 2²⁴). Not for `5412345.456`, which is
/// `5412345.5` in `f32`, nor `123456789`.
fn f32_states(text: &str, value: f64) -> bool {
    if !value.is_finite() {
        // `inf` and `nan` are what they are in f32 too (and refused later, as from any file).
        return true;
    }
    let rounded = value as f32;
    if !rounded.is_finite() {
        // Beyond f32's range.
        return false;
    }
    let error = (rounded as f64 - value).abs();
    if error == 0.0 {
        return true;
    }
    // The unit of the text's last digit: 10^(exponent − digits after the point).
    let (mantissa, exponent) = match text.find(['e', 'E']) {
        Some(at) => (&text[..at], text[at + 1..].parse::<i32>().unwrap_or(0)),
        None => (text, 0),
    };
    let decimals = mantissa
        .split_once('.')
        .map_or(0, |(_, fraction)| fraction.len() as i32);
    // (A millionth of slack: a tie, `0.0717773438` for the f32 0.07177734375, is exactly half
    // a unit apart, which f64 arithmetic may put a hair above.)
    error <= 0.5 * 10f64.powi(exponent.saturating_sub(decimals)) * (1.0 + 1e-6)
}

/// Reads the binary `.bnpts` file `path` (see [`read_binary_from`]); errors name the path. A
/// file whose length is not a whole number of records is refused before anything is read.
pub fn read_binary(path: &Path, colors: bool) -> io::Result<PlyPoints> {
    let (file, len) = open(path)?;
    let record = binary_record_bytes(colors) as u64;
    let mut capacity = 0;
    if let Some(len) = len {
        if !len.is_multiple_of(record) {
            return Err(invalid(Some(path), whole_records(len, colors)));
        }
        capacity = usize::try_from(len / record).unwrap_or(0);
    }
    read_binary_impl(file, colors, Some(path), capacity)
}

/// Reads `.bnpts` records (24 bytes, or 27 with `colors`: see the
/// [module documentation](self)) until the end of `reader`; a partial record at the end is an
/// error.
pub fn read_binary_from(reader: impl Read, colors: bool) -> io::Result<PlyPoints> {
    read_binary_impl(reader, colors, None, 0)
}

/// Why `len` bytes are not a `.bnpts` file of the layout asked for.
fn whole_records(len: u64, colors: bool) -> String {
    let record = binary_record_bytes(colors);
    let other = binary_record_bytes(!colors);
    let hint = if len.is_multiple_of(other as u64) {
        format!(
            "; it is a whole number of {other}-byte records, the layout {} colours",
            if colors { "without" } else { "with" }
        )
    } else {
        String::new()
    };
    format!(
        "{len} bytes are not a whole number of {record}-byte records (x y z nx ny nz as \
         little-endian float32{}){hint}",
        if colors { ", then r g b as bytes" } else { "" }
    )
}

fn read_binary_impl(
    mut reader: impl Read,
    colors: bool,
    path: Option<&Path>,
    capacity: usize,
) -> io::Result<PlyPoints> {
    let record = binary_record_bytes(colors);
    let mut points = PlyPoints::default();
    points.positions.reserve_exact(capacity);
    points.normals.reserve_exact(capacity);
    let mut rgb: Vec<[f32; 3]> = Vec::with_capacity(if colors { capacity } else { 0 });
    let mut buf = vec![0u8; record * 40_000];
    let mut total = 0u64;
    loop {
        // Fill the buffer (a read may return less than asked) or reach the end.
        let mut filled = 0;
        while filled < buf.len() {
            match reader.read(&mut buf[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    return Err(match path {
                        Some(p) => {
                            io::Error::new(e.kind(), format!("{}: cannot read: {e}", p.display()))
                        }
                        None => e,
                    })
                }
            }
        }
        total += filled as u64;
        for r in buf[..filled].chunks_exact(record) {
            let f =
                |k: usize| f32::from_le_bytes([r[4 * k], r[4 * k + 1], r[4 * k + 2], r[4 * k + 3]]);
            points.positions.push([f(0), f(1), f(2)]);
            points.normals.push([f(3), f(4), f(5)]);
            if colors {
                rgb.push([r[24], r[25], r[26]].map(|c| (c as f64 / 255.0) as f32));
            }
        }
        if filled < buf.len() {
            if !filled.is_multiple_of(record) {
                return Err(invalid(path, whole_records(total, colors)));
            }
            break;
        }
    }
    if colors {
        points.colors = Some(Colors::Rgb(rgb));
    }
    Ok(points)
}

/// Writes `points` as an ASCII points file (see [`write_ascii_to`]).
pub fn write_ascii(path: &Path, points: &PlyPoints) -> io::Result<()> {
    write_file(path, |w| write_ascii_to(w, points))
}

/// Writes `points` one per line: `x y z`, then `nx ny nz` when there are normals, then
/// `r g b` (0–255, rounded) when there are colours (an alpha is dropped). Colours without
/// normals are refused: no layout has them. The other attributes are not written.
pub fn write_ascii_to(w: impl Write, points: &PlyPoints) -> io::Result<()> {
    let rgb = check_points(points)?;
    let mut chunk = Chunk::new(w);
    let mut line: Vec<u8> = Vec::with_capacity(128);
    for (i, [x, y, z]) in points.positions.iter().enumerate() {
        line.clear();
        // Writing to a Vec cannot fail.
        let _ = write!(line, "{x} {y} {z}");
        if let Some([nx, ny, nz]) = points.normals.get(i) {
            let _ = write!(line, " {nx} {ny} {nz}");
        }
        if let Some(rgb) = &rgb {
            let [r, g, b] = rgb(i);
            let _ = write!(line, " {r} {g} {b}");
        }
        line.push(b'\n');
        chunk.put(&line)?;
    }
    chunk.finish()
}

/// Writes `points` as a binary `.bnpts` file (see [`write_binary_to`]).
pub fn write_binary(path: &Path, points: &PlyPoints) -> io::Result<()> {
    write_file(path, |w| write_binary_to(w, points))
}

/// Writes `points` as `.bnpts` records: little-endian `float32` `x y z nx ny nz`, then `r g b`
/// as bytes (0–255, rounded) when there are colours (27-byte records; read them back with
/// `colors` set). The normals are required; the other attributes are not written.
pub fn write_binary_to(w: impl Write, points: &PlyPoints) -> io::Result<()> {
    let rgb = check_points(points)?;
    if points.normals.is_empty() && !points.positions.is_empty() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "a .bnpts file holds normals with every point, and these points have none",
        ));
    }
    let mut chunk = Chunk::new(w);
    let mut record = Vec::with_capacity(27);
    for (i, (p, n)) in points.positions.iter().zip(&points.normals).enumerate() {
        record.clear();
        for v in p.iter().chain(n) {
            record.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(rgb) = &rgb {
            record.extend_from_slice(&rgb(i));
        }
        chunk.put(&record)?;
    }
    chunk.finish()
}

/// Checks that `points`' normals and colours have one entry per position; returns, when there
/// are colours, each point's RGB as bytes (0–255, rounded, clamped).
fn check_points(points: &PlyPoints) -> io::Result<Option<impl Fn(usize) -> [u8; 3] + '_>> {
    let n = points.positions.len();
    let normals = points.normals.len();
    if normals != 0 && normals != n {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{normals} normals for {n} points"),
        ));
    }
    let Some(colors) = &points.colors else {
        return Ok(None);
    };
    if colors.len() != n {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} colours for {n} points", colors.len()),
        ));
    }
    if normals == 0 && n != 0 {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "colours need normals in PoissonRecon's layouts (x y z nx ny nz r g b)",
        ));
    }
    let flat = colors.as_flattened();
    let components = colors.components();
    Ok(Some(move |i: usize| {
        [0, 1, 2].map(|k| {
            (flat[i * components + k] as f64 * 255.0)
                .round()
                .clamp(0.0, 255.0) as u8
        })
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three points with exact values (colours k/255 as the readers make them).
    fn sample(normals: bool, colors: bool) -> PlyPoints {
        let uchar = |c: [u8; 3]| c.map(|v| (v as f64 / 255.0) as f32);
        PlyPoints {
            positions: vec![[0.5, -1.25, 3.0e-7], [1.0e6, 2.5, -0.1], [0.0, 0.0, 0.0]],
            positions_f64: None,
            normals: if normals {
                vec![
                    [0.0, 0.0, 1.0],
                    [0.6, 0.8, 0.0],
                    [-0.33333334, 0.6666667, -0.6666667],
                ]
            } else {
                Vec::new()
            },
            colors: colors.then(|| {
                Colors::Rgb(vec![
                    uchar([255, 0, 7]),
                    uchar([1, 2, 3]),
                    uchar([128, 64, 32]),
                ])
            }),
            ..PlyPoints::default()
        }
    }

    fn temp_path(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("psr-npts-test-{}-{name}", std::process::id()))
    }

    /// Proves: each ASCII layout (3, 6 and 9 numbers a line) round-trips exactly, through
    /// memory and through a file.
    #[test]
    fn ascii_round_trips_in_each_layout() {
        for (normals, colors, columns) in [(false, false, 3), (true, false, 6), (true, true, 9)] {
            let points = sample(normals, colors);
            let mut bytes = Vec::new();
            write_ascii_to(&mut bytes, &points).unwrap();
            let text = String::from_utf8(bytes).unwrap();
            assert!(
                text.lines().all(|l| l.split(' ').count() == columns),
                "{text}"
            );
            assert_eq!(
                read_ascii_from(text.as_bytes()).unwrap(),
                points,
                "{columns}"
            );
        }
        let path = temp_path("cloud.npts");
        let points = sample(true, true);
        write_ascii(&path, &points).unwrap();
        let back = read_ascii(&path);
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back.unwrap(), points);
    }

    /// Proves: blank lines, `#` comments, tabs, runs of spaces, CRLF line ends, exponents and
    /// a last line without its end are read; colours come out 0-1 as from a PLY uchar.
    #[test]
    fn ascii_reads_what_other_programs_write() {
        let text = "# x y z nx ny nz r g b\n\n  1\t2  3 0 0 1 255 0 51\r\n\t\r\n\
                    -1e-3 4.5E2 +6 1 0 0 0 0 0\n# done\n7 8 9 0 1 0 1 2 3";
        let points = read_ascii_from(text.as_bytes()).unwrap();
        assert_eq!(
            points.positions,
            vec![[1.0, 2.0, 3.0], [-1e-3, 450.0, 6.0], [7.0, 8.0, 9.0]]
        );
        assert_eq!(
            points.normals,
            vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        );
        let Some(Colors::Rgb(colors)) = &points.colors else {
            panic!("colours expected")
        };
        assert_eq!(colors[0], [1.0, 0.0, 0.2]);
        assert_eq!(points.color_type, ColorType::U8);
        assert!(read_ascii_from(&b""[..]).unwrap().is_empty());
        assert!(read_ascii_from(&b"# only a comment\n\n"[..])
            .unwrap()
            .is_empty());
    }

    /// Proves: positions that state more than `f32` holds (georeferenced coordinates, values
    /// beyond f32's range, a 9-digit integer) are kept in `f64` too, exactly as written;
    /// positions that `f32` holds to the text's last digit (`%.9g` of an `f32`, its shortest
    /// form, six decimals) are not, and normals never make it so.
    #[test]
    fn ascii_keeps_positions_in_f64_when_f32_would_lose_them() {
        let far =
            read_ascii_from(&b"512345.123 5412345.456 234.5 0 0 1\n1 2 3 0 1 0\n"[..]).unwrap();
        assert_eq!(
            far.positions_f64,
            Some(vec![[512345.123, 5412345.456, 234.5], [1.0, 2.0, 3.0]])
        );
        assert_eq!(far.positions[0], [512345.12, 5412345.5, 234.5]);
        assert_eq!(far.normals[1], [0.0, 1.0, 0.0]);
        let huge = read_ascii_from(&b"1e39 0 0\n"[..]).unwrap();
        assert_eq!(huge.positions_f64, Some(vec![[1e39, 0.0, 0.0]]));
        let integer = read_ascii_from(&b"123456789 0 0\n"[..]).unwrap();
        assert_eq!(integer.positions_f64, Some(vec![[123456789.0, 0.0, 0.0]]));
        for near in [
            "0.123456 -4.5 1e-7 0.12345678901 0 0",
            "0.12345679 0.100000001 -33.333332 0 0 1",
            "1234567.000 0.25 -16777216 0 0 1",
            "12.345678 5.2e-3 -7.00000313e+05 0 0 1",
            "0.0717773438 -0.0200195312 0.139648438 0 0 1",
        ] {
            let points = read_ascii_from(near.as_bytes()).unwrap();
            assert_eq!(points.positions_f64, None, "{near}");
        }
    }

    /// Proves: every malformed ASCII file is an error that names the line and says what is
    /// wrong, the path in front when read from a file.
    #[test]
    fn ascii_errors_name_the_line() {
        for (text, expected) in [
            (
                "1 2 3 0 0 1\n4 5 6 0 0 1\n7 8 9\n",
                "line 3: 3 numbers, but line 1",
            ),
            (
                "# c\n1 2 3\n4 5 6 7\n",
                "line 3: 4 numbers, but line 2 (the first point) has 3",
            ),
            ("1 2 3 4\n", "line 1: 4 numbers: a point is 3 (x y z), 6"),
            ("1 2 3 0 0 1 2 3 4 5\n", "line 1: 10 numbers"),
            ("1 2 3\n1 2 z\n", "line 2: 'z' is not a number"),
            ("1,2,3\n", "line 1: '1,2,3' is not a number"),
            (
                "1 2 3 0 0 1 0 256 0\n",
                "line 1: colour component 256 is outside 0-255",
            ),
            ("1 2 3 0 0 1 0 -1 0\n", "line 1: colour component -1"),
        ] {
            let message = read_ascii_from(text.as_bytes()).unwrap_err().to_string();
            assert!(message.contains(expected), "{text:?}: {message}");
        }
        let binary = read_ascii_from(&b"1 2 3\n\xff\xfe\n"[..])
            .unwrap_err()
            .to_string();
        assert!(binary.contains("line 2: not text"), "{binary}");
        let path = temp_path("bad.xyz");
        std::fs::write(&path, "1 2 3\n4 5\n").unwrap();
        let message = read_ascii(&path).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(
            message.starts_with(&format!("{}: line 2:", path.display())),
            "{message}"
        );
        let missing = read_ascii(&temp_path("absent.xyz"))
            .unwrap_err()
            .to_string();
        assert!(missing.contains("absent.xyz: cannot open"), "{missing}");
    }

    /// Proves: .bnpts round-trips with and without colours, as 24- and 27-byte records of
    /// little-endian floats (and bytes), through memory and through a file.
    #[test]
    fn binary_round_trips_with_and_without_colours() {
        for colors in [false, true] {
            let points = sample(true, colors);
            let mut bytes = Vec::new();
            write_binary_to(&mut bytes, &points).unwrap();
            assert_eq!(bytes.len(), 3 * binary_record_bytes(colors));
            assert_eq!(bytes[..4], 0.5f32.to_le_bytes());
            assert_eq!(bytes[20..24], 1.0f32.to_le_bytes(), "nz of the first point");
            if colors {
                assert_eq!(bytes[24..27], [255, 0, 7]);
            }
            assert_eq!(read_binary_from(&bytes[..], colors).unwrap(), points);
            let path = temp_path("cloud.bnpts");
            write_binary(&path, &points).unwrap();
            let back = read_binary(&path, colors);
            std::fs::remove_file(&path).unwrap();
            assert_eq!(back.unwrap(), points, "colors={colors}");
        }
        assert!(read_binary_from(&b""[..], false).unwrap().is_empty());
    }

    /// Proves: a length that is not whole records is refused (before reading, for a file),
    /// with a hint when the other layout would fit; a stream cut inside a record is an error.
    #[test]
    fn binary_lengths_must_be_whole_records() {
        let mut bytes = Vec::new();
        write_binary_to(&mut bytes, &sample(true, true)).unwrap();
        // 81 bytes: three 27-byte records, not 24-byte ones.
        let path = temp_path("colours.bnpts");
        std::fs::write(&path, &bytes).unwrap();
        let message = read_binary(&path, false).unwrap_err().to_string();
        assert!(read_binary(&path, true).is_ok());
        std::fs::remove_file(&path).unwrap();
        assert!(
            message.contains("81 bytes are not a whole number of 24-byte records")
                && message.contains("27-byte records, the layout with colours"),
            "{message}"
        );
        let message = read_binary_from(&bytes[..80], true)
            .unwrap_err()
            .to_string();
        assert!(message.contains("80 bytes"), "{message}");
        // 72 bytes: three 24-byte records, not 27-byte ones (and no hint fits 27).
        let mut plain = Vec::new();
        write_binary_to(&mut plain, &sample(true, false)).unwrap();
        plain.push(0);
        let message = read_binary_from(&plain[..], false).unwrap_err().to_string();
        assert!(
            message.contains("73 bytes") && !message.contains("layout"),
            "{message}"
        );
    }

    /// Proves: the writers refuse what their layouts cannot hold.
    #[test]
    fn writers_refuse_what_the_layouts_cannot_hold() {
        let sink = || io::sink();
        assert!(
            write_binary_to(sink(), &sample(false, false)).is_err(),
            "no normals"
        );
        let mut colours_only = sample(false, false);
        colours_only.colors = sample(true, true).colors;
        assert!(write_ascii_to(sink(), &colours_only).is_err());
        let mut short = sample(true, false);
        short.normals.pop();
        assert!(write_ascii_to(sink(), &short).is_err());
        assert!(write_binary_to(sink(), &short).is_err());
    }
}
