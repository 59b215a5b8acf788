//! What real exports carry that the layouts' own tests do not: a phone's
//! time stamps that step back, a locale's numbers (a decimal comma, the
//! Unicode minus sign in an exponent, digits grouped by a no-break space),
//! Tracker's export without its track-name line, phyphox's own
//! `.phyphox` file, and archives that list too much. Each written byte for
//! byte as the tool writes it from a simulated lab-like swing
//! ([`host_tests::exports`]), imported with the defaults at `dt = 0.04`
//! and read by the blob for real rigs within 2% of the length. None of it
//! is anyone's data.

use std::io::Write;

use host_tests::exports::{
    DT, Swing, assert_within_2, file, normal, phyphox_gyroscope, sci, swing,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use trainer_core::data::import::{self, ImportOptions};

/// The import's options: the defaults at the rig blob's interval.
fn opts() -> ImportOptions {
    ImportOptions {
        dt: DT,
        ..ImportOptions::default()
    }
}

/// The import's error for the file, in full.
fn import_error(path: &std::path::Path) -> String {
    format!(
        "{:#}",
        import::import_with_layouts(&[path.to_path_buf()], &opts()).unwrap_err()
    )
}

/// A phone's gyroscope at 100 Hz for 45 s whose stamps step back 12
/// times (a sample's row below the one 10 ms after it, as a real phyphox
/// export had them): put in order, counted, read within 2%. The same
/// file scrambled, or written backwards, is refused with what it is.
#[test]
fn a_phones_stamps_that_step_back_are_put_in_order() {
    let mut rng = ChaCha8Rng::seed_from_u64(81);
    let s = swing(0.62, 0.45, 0.01, 45.0);
    let text = phyphox_gyroscope(&s, &mut rng);
    let mut lines: Vec<&str> = text.lines().collect();
    let mut swapped = Vec::new();
    while swapped.len() < 12 {
        let k = rng.random_range(2..lines.len() - 1);
        if swapped.iter().all(|&j: &usize| j.abs_diff(k) > 2) {
            lines.swap(k, k + 1);
            swapped.push(k);
        }
    }
    let back = lines.join("\n") + "\n";
    let p = file("gyroscope-back.csv", back.as_bytes());
    let layouts = assert_within_2(&p, &[0.62]);
    assert_eq!(layouts[0].reordered, 12);
    assert!(
        layouts[0]
            .describe()
            .contains("12 rows out of time order put in order")
    );
    let (_, sources) = import::import_with_sources(&[p], &opts()).unwrap();
    assert_eq!(sources[0].reordered, 12);
    // Backwards throughout, and scrambled.
    let mut rows = lines[1..].to_vec();
    rows.reverse();
    let reversed = format!("{}\n{}\n", lines[0], rows.join("\n"));
    let e = import_error(&file("gyroscope-reversed.csv", reversed.as_bytes()));
    assert!(e.contains("run backwards throughout"), "{e}");
    for k in (1..rows.len()).rev() {
        rows.swap(k, rng.random_range(0..=k));
    }
    let scrambled = format!("{}\n{}\n", lines[0], rows.join("\n"));
    let e = import_error(&file("gyroscope-scrambled.csv", scrambled.as_bytes()));
    assert!(e.contains("scrambled"), "{e}");
}

/// A number as Tracker writes it in a Norwegian locale: four significant
/// digits, a decimal comma, the minus sign U+2212 in the mantissa and
/// the exponent (`6,442E−2`, `−1,234E0`).
fn norwegian(v: f64) -> String {
    format!("{v:.3E}")
        .replace('.', ",")
        .replace('-', "\u{2212}")
}

/// Tracker's Export Data in a Norwegian locale: `t x y` with no
/// track-name line, tab-separated, every number as [`norwegian`]; the
/// bob in metres about the pivot at the origin, y up, 30 Hz.
#[test]
fn a_tracker_export_in_a_norwegian_locale() {
    let mut rng = ChaCha8Rng::seed_from_u64(82);
    let s = swing(0.85, 0.5, 1.0 / 30.0, 45.0);
    let mut text = String::from("t\tx\ty\n");
    for (t, x) in s.t.iter().zip(&s.x) {
        let (bx, by) = (s.length * x[0].sin(), -s.length * x[0].cos());
        text.push_str(&format!(
            "{}\t{}\t{}\n",
            norwegian(*t),
            norwegian(bx + 1e-3 * normal(&mut rng)),
            norwegian(by + 1e-3 * normal(&mut rng))
        ));
    }
    assert!(text.contains("E\u{2212}2"), "no small number written");
    let layouts = assert_within_2(&file("tracker-nb.txt", text.as_bytes()), &[0.85]);
    assert_eq!(layouts[0].tool, Some("Tracker"));
    assert!(matches!(
        layouts[0].angle_from,
        import::AngleFrom::Position { .. }
    ));
}

/// The other forms of a number, one column each way: a time in
/// milliseconds with digits grouped by a no-break or a thin space and a
/// decimal comma; an angle in degrees with each minus-like sign (U+2212,
/// U+2012, U+2013, U+FE63, U+FF0D) in turn, `+` in its exponent;
/// semicolon-separated. Then the same numbers in a comma-separated file,
/// each quoted.
#[test]
fn every_form_of_a_number_reads() {
    let mut rng = ChaCha8Rng::seed_from_u64(83);
    let s = swing(0.4, 0.6, 0.02, 40.0);
    let minus = ['\u{2212}', '\u{2012}', '\u{2013}', '\u{FE63}', '\u{FF0D}'];
    let group = ['\u{A0}', '\u{2009}', '\u{202F}'];
    let forms = |k: usize, t: f64, a: f64| {
        let ms = format!("{:.1}", 1000.0 * t).replace('.', ",");
        let (int, frac) = ms.split_once(',').unwrap_or((&ms, "0"));
        let grouped = match int.len() {
            n if n > 3 => format!("{}{}{}", &int[..n - 3], group[k % 3], &int[n - 3..]),
            _ => int.to_string(),
        };
        let angle = format!("{a:.4E}")
            .replace('E', "E+")
            .replace("E+-", "E-")
            .replace('.', ",")
            .replace('-', &minus[k % 5].to_string());
        (format!("{grouped},{frac}"), angle)
    };
    let mut semicolons = String::from("Time (ms);Angle (°)\n");
    let mut quoted = String::from("\"Time (ms)\",\"Angle (°)\"\n");
    for (k, (t, x)) in s.t.iter().zip(&s.x).enumerate() {
        let a = (x[0] + 0.002 * normal(&mut rng)).to_degrees();
        let (time, angle) = forms(k, *t, a);
        semicolons.push_str(&format!("{time};{angle}\n"));
        quoted.push_str(&format!("\"{time}\",\"{angle}\"\n"));
    }
    assert!(semicolons.contains("E+1") && semicolons.contains('\u{FF0D}'));
    assert_within_2(&file("forms.csv", semicolons.as_bytes()), &[0.4]);
    assert_within_2(&file("forms-quoted.csv", quoted.as_bytes()), &[0.4]);
}

/// A buffer's value as phyphox writes it into a saved file: Java's
/// `DecimalFormat("0.#########E0")` (Locale.ENGLISH): at most ten
/// significant digits, trailing zeros dropped, no `+` (`4.4677716E-2`,
/// `0E0`, `-1.2345E-3`).
fn java_sci(v: f64) -> String {
    let s = format!("{v:.9E}");
    let (mantissa, exponent) = s.split_once('E').unwrap_or((&s, "0"));
    let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
    format!("{mantissa}E{exponent}")
}

/// A saved `.phyphox` file as phyphox-android's `writeStateFile` writes
/// it (`PhyphoxExperiment.java`): the experiment's XML as loaded, an
/// XML declaration before it, each container given `init` with its
/// values, and the state's title, colour and events after `</export>`.
/// `containers` are `(attributes, name, values)`; `export` the sets.
fn saved_phyphox(
    title: &str,
    containers: &[(&str, &str, Vec<f64>)],
    input: &str,
    export: &str,
) -> String {
    let mut text = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?><phyphox version=\"1.14\" locale=\"en\">\n  \
         <title>{title}</title>\n  <category>Raw Sensors</category>\n  \
         <icon format=\"base64\">iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg==</icon>\n  \
         <description>Get raw data from the gyroscope.</description>\n  \
         <link label=\"Wiki\">http://phyphox.org/wiki/index.php?title=Sensor:_Gyroscope</link>\n  \
         <translations>\n    <translation locale=\"de\">\n      <title>Gyroskop (Drehrate)</title>\n      \
         <category>Sensoren</category>\n      <string original=\"Graph\">Graph</string>\n    </translation>\n  </translations>\n  \
         <data-containers>\n"
    );
    for (attributes, name, values) in containers {
        let init: Vec<String> = values.iter().map(|v| java_sci(*v)).collect();
        text.push_str(&format!(
            "    <container {attributes} init=\"{}\">{name}</container>\n",
            init.join(",")
        ));
    }
    text.push_str(&format!(
        "  </data-containers>\n  <input>\n{input}  </input>\n  <views>\n    <view label=\"Graph\">\n      \
         <graph label=\"Gyroscope x\" labelX=\"t (s)\" labelY=\"w (rad/s)\">\n        \
         <input axis=\"x\">gyr_time</input>\n        <input axis=\"y\">gyrX</input>\n      </graph>\n    </view>\n  </views>\n  \
         <export>\n{export}  </export>\n\
         <state-title>Measurement 07.12.26 13:05</state-title><color>blue</color><events><start experimentTime=\"0.0\" systemTime=\"1796648700000\"/><pause experimentTime=\"60.01\" systemTime=\"1796648760010\"/></events></phyphox>"
    ));
    text
}

/// The experiment's `<input>`: the gyroscope (`attributes` after its
/// type) writing `gyrX`, `gyrY`, `gyrZ` and `gyr_time`, then `more`.
fn gyroscope_input(attributes: &str, more: &str) -> String {
    format!(
        "    <sensor type=\"gyroscope\"{attributes}>\n      <output component=\"x\">gyrX</output>\n      \
         <output component=\"y\">gyrY</output>\n      <output component=\"z\">gyrZ</output>\n      \
         <output component=\"t\">gyr_time</output>\n{more}    </sensor>\n"
    )
}

/// The gyroscope's rates of `s` as the phone measures them (the swing on
/// z tilted 8 degrees into x, biases, noise), with their absolute.
fn gyro_rates(s: &Swing, rng: &mut ChaCha8Rng) -> [Vec<f64>; 4] {
    let tilt = 8f64.to_radians();
    let mut w: [Vec<f64>; 4] = Default::default();
    for x in &s.x {
        let v = [
            x[1] * tilt.sin() + 0.01 + 0.005 * normal(rng),
            -0.01 + 0.005 * normal(rng),
            x[1] * tilt.cos() + 0.01 + 0.005 * normal(rng),
        ];
        let abs = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        for (c, value) in w.iter_mut().zip(v.iter().chain([&abs])) {
            c.push(*value);
        }
    }
    w
}

/// phyphox's "Gyroscope (rotation rate)" saved with 60 s of data: its
/// containers and export as phyphox-experiments' `gyroscope.phyphox`
/// defines them; imported as its CSV export of the same numbers imports
/// (the same rollout, value for value), within 2%. A saved file whose
/// buffers hold nothing gets an error naming them.
#[test]
fn phyphoxs_own_file_imports_as_its_csv_export() {
    let mut rng = ChaCha8Rng::seed_from_u64(84);
    let s = swing(0.55, 0.5, 0.01, 60.0);
    let t: Vec<f64> = s.t.iter().map(|t| t + 0.0446777).collect();
    let [x, y, z, abs] = gyro_rates(&s, &mut rng);
    let input = gyroscope_input("", "      <output component=\"abs\">gyr</output>\n");
    let export = "    <set name=\"Raw Data\">\n      <data name=\"Time (s)\">gyr_time</data>\n      \
                  <data name=\"Gyroscope x (rad/s)\">gyrX</data>\n      <data name=\"Gyroscope y (rad/s)\">gyrY</data>\n      \
                  <data name=\"Gyroscope z (rad/s)\">gyrZ</data>\n      <data name=\"Absolute (rad/s)\">gyr</data>\n    </set>\n";
    let containers = [
        ("size=\"0\"", "gyrX", x.clone()),
        ("size=\"0\"", "gyrY", y.clone()),
        ("size=\"0\"", "gyrZ", z.clone()),
        ("size=\"0\"", "gyr", abs.clone()),
        ("size=\"0\"", "gyr_time", t.clone()),
    ];
    let saved = saved_phyphox("Gyroscope (rotation rate)", &containers, &input, export);
    let p = file(
        "Gyroscope rotation rate 2026-12-07 13-05-00.phyphox",
        saved.as_bytes(),
    );
    let layouts = assert_within_2(&p, &[0.55]);
    assert_eq!(layouts[0].tool, Some("phyphox"));
    // Its CSV export: the set `Raw Data`, the numbers as `0.000000000E0`.
    let mut csv = String::from(
        "\"Time (s)\",\"Gyroscope x (rad/s)\",\"Gyroscope y (rad/s)\",\"Gyroscope z (rad/s)\",\"Absolute (rad/s)\"\n",
    );
    for k in 0..t.len() {
        let row = [t[k], x[k], y[k], z[k], abs[k]].map(sci);
        csv.push_str(&(row.join(",") + "\n"));
    }
    let from_csv = import::import(&[file("Raw Data.csv", csv.as_bytes())], &opts()).unwrap();
    let from_file = import::import(&[p], &opts()).unwrap();
    assert_eq!(from_file.rollouts, from_csv.rollouts);
    // No buffer with values: the buffers named, at most 10 and how many more.
    let empty: Vec<(&str, &str, Vec<f64>)> = [
        "a", "b", "c", "d", "e", "f", "g", "h", "i", "j", "k", "gyr_time",
    ]
    .iter()
    .map(|n| ("size=\"0\"", *n, Vec::new()))
    .collect();
    let saved = saved_phyphox("Gyroscope (rotation rate)", &empty, &input, export);
    let e = import_error(&file("empty.phyphox", saved.as_bytes()));
    assert!(
        e.contains("its buffers are a (0 values), b (0 values)") && e.contains("and 2 more"),
        "{e}"
    );
}

/// phyphox's "Pendulum" saved: its rotation buffers hold the last 500
/// samples at 50 Hz (10 s), beside the experiment's analysis buffers and
/// its three export sets (`Raw Data`, `Autocorrelation`, `Resonance`), as
/// phyphox-experiments' `pendulum.phyphox` defines them: the raw data's
/// rotation rates are imported (the other sets passed over), within 2%.
#[test]
fn phyphoxs_pendulum_file_imports_its_rotation_buffers() {
    let mut rng = ChaCha8Rng::seed_from_u64(85);
    let s = swing(0.35, 0.4, 0.02, 9.98);
    let t: Vec<f64> = s.t.iter().map(|t| t + 31.2).collect();
    let [x, y, z, _] = gyro_rates(&s, &mut rng);
    let input = gyroscope_input(" rate=\"50\"", "");
    let export = "    <set name=\"Raw Data\">\n      <data name=\"Time (s)\">gyr_time</data>\n      \
                  <data name=\"Rotation x (rad/s)\">gyrX</data>\n      <data name=\"Rotation y (rad/s)\">gyrY</data>\n      \
                  <data name=\"Rotation z (rad/s)\">gyrZ</data>\n    </set>\n    \
                  <set name=\"Autocorrelation\">\n      <data name=\"Time shift (s)\">autocorrelation_t</data>\n      \
                  <data name=\"Autocorrelation of sum\">autocorrelation</data>\n    </set>\n    \
                  <set name=\"Resonance\">\n      <data name=\"Frequency (Hz)\">frequencyhist</data>\n      \
                  <data name=\"Rel. amplitude (a.u.)\">relamplitude</data>\n    </set>\n";
    let lags: Vec<f64> = (0..500).map(|k| k as f64 * 0.02).collect();
    let period = 2.0 * std::f64::consts::PI * (0.35f64 / 9.81).sqrt();
    let correlation: Vec<f64> = lags
        .iter()
        .map(|l| (2.0 * std::f64::consts::PI * l / period).cos())
        .collect();
    let containers = [
        ("size=\"500\"", "gyr_time", t),
        ("size=\"500\"", "gyrX", x),
        ("size=\"500\"", "gyrY", y),
        ("size=\"500\"", "gyrZ", z),
        ("size=\"500\"", "anyGyr", Vec::new()),
        ("size=\"1\"", "count", vec![500.0]),
        ("size=\"500\"", "autocorrelation_t", lags),
        ("size=\"500\"", "autocorrelation", correlation),
        ("", "dt", vec![0.02]),
        (
            "size=\"20\" static=\"true\"",
            "factors",
            (1..=20).map(f64::from).collect(),
        ),
        ("size=\"1\"", "period", vec![period]),
        ("size=\"0\"", "frequencyhist", vec![1.0 / period; 3]),
        ("size=\"0\"", "relamplitude", vec![1.0, 0.99, 0.98]),
        ("", "length", vec![0.35]),
    ];
    let saved = saved_phyphox("Pendulum", &containers, &input, export);
    let layouts = assert_within_2(
        &file("Pendulum 2026-12-07 13-05-00.phyphox", saved.as_bytes()),
        &[0.35],
    );
    assert_eq!(layouts[0].file.rsplit(':').next(), Some("Raw Data"));
}

/// A zip of 20,000 tiny entries, none a recording: the error lists ten
/// and says how many more, not all of them.
#[test]
fn a_zip_of_many_entries_gives_a_short_error() {
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default();
    for k in 0..20_000 {
        zip.start_file(format!("entry-{k}.csv"), options).unwrap();
        zip.write_all(b"a,b\nx,y\n").unwrap();
    }
    let bytes = zip.finish().unwrap().into_inner();
    let e = import_error(&file("many.zip", &bytes));
    assert!(e.len() < 1000, "{} bytes: {}", e.len(), &e[..300]);
    assert!(e.contains("and 19990 more"), "{e}");
}
