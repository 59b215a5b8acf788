//! Every lab tool's layout, written byte for byte from a simulated
//! lab-like swing (a string with drag on the bob, the angle's zero 0.03
//! rad off, a tracker's or a sensor's noise), imported with the default
//! options at `dt = 0.04` and read by the blob for real rigs
//! (`weights/rig.kkf`, g = 9.81 declared): the length within 2% at the end
//! of every recording. None of it is anyone's data.
//!
//! The layouts: phyphox's gyroscope export (comma, quoted names, numbers
//! like `9.969000006E-3`, the rate only: 90 s with biases of 0.01 rad/s
//! and noise of 0.005 rad/s), phyphox's pendulum raw data (tab, decimal
//! comma), its zip export and a workbook, Tracker's export (the track's
//! name, then `t x y` in metres about the pivot; and in pixels, y down,
//! the pivot off the origin, one frame a glitch), Vernier Graphical
//! Analysis (degrees, `Latest:`), PASCO Capstone (a byte-order mark, tab,
//! decimal comma, two runs side by side, the shorter padded with empty
//! cells), and an IMU logger's messages before rows written as lists.

use std::io::Write;

use host_tests::exports::{
    assert_within_2, file, normal, phyphox_gyroscope, phyphox_pendulum, sci, swing, tracker,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use trainer_core::data::import::{self, AngleFrom, ImportOptions};

/// The rate-only and tab-with-decimal-comma layouts of phyphox.
#[test]
fn phyphox_exports_read_within_2_percent() {
    let mut rng = ChaCha8Rng::seed_from_u64(38);
    let gyro = swing(0.45, 0.5, 0.01, 90.0);
    let p = file(
        "gyroscope.csv",
        phyphox_gyroscope(&gyro, &mut rng).as_bytes(),
    );
    let layouts = assert_within_2(&p, &[0.45]);
    assert_eq!(layouts[0].tool, Some("phyphox"));
    let AngleFrom::Integrated { axis, .. } = &layouts[0].angle_from else {
        panic!("{:?}", layouts[0].angle_from)
    };
    assert_eq!(axis, "Gyroscope z (rad/s)");
    let pendulum = swing(1.1, 0.3, 0.02, 60.0);
    let p = file(
        "pendulum.csv",
        phyphox_pendulum(&pendulum, &mut rng).as_bytes(),
    );
    let layouts = assert_within_2(&p, &[1.1]);
    assert!(matches!(
        layouts[0].angle_from,
        AngleFrom::Integrated { .. }
    ));
}

/// phyphox's zip export (a CSV a set, its metadata beside) and a
/// workbook with the same set as a sheet.
#[test]
fn phyphox_zip_and_workbook_read_within_2_percent() {
    let mut rng = ChaCha8Rng::seed_from_u64(39);
    let s = swing(0.7, 0.4, 0.01, 40.0);
    let csv = phyphox_gyroscope(&s, &mut rng);
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let opts = zip::write::SimpleFileOptions::default();
    zip.start_file("Gyroscope.csv", opts).unwrap();
    zip.write_all(csv.as_bytes()).unwrap();
    zip.start_file("meta/device.csv", opts).unwrap();
    zip.write_all(b"\"property\",\"value\"\n\"deviceModel\",\"Pixel\"\n")
        .unwrap();
    let bytes = zip.finish().unwrap().into_inner();
    assert_within_2(&file("gyroscope.zip", &bytes), &[0.7]);
    assert_within_2(&file("gyroscope.xlsx", &workbook(&csv)), &[0.7]);
}

/// Tracker in metres about the pivot, and in pixels (y down, 400 px a
/// metre) with the pivot at (640, 120) and one frame on another object.
#[test]
fn tracker_exports_read_within_2_percent() {
    let mut rng = ChaCha8Rng::seed_from_u64(40);
    let s = swing(0.9, 0.6, 1.0 / 30.0, 45.0);
    let metres = file(
        "tracker-m.txt",
        tracker(&s, &mut rng, |x, y| (x, y)).as_bytes(),
    );
    let layouts = assert_within_2(&metres, &[0.9]);
    assert_eq!(layouts[0].tool, Some("Tracker"));
    assert!(matches!(
        layouts[0].angle_from,
        AngleFrom::Position {
            from: import::PivotFrom::Origin,
            ..
        }
    ));
    let mut text = tracker(&s, &mut rng, |x, y| (640.0 + 400.0 * x, 120.0 - 400.0 * y));
    let lines: Vec<String> = text.lines().map(String::from).collect();
    let mut fields: Vec<String> = lines[300].split('\t').map(String::from).collect();
    fields[1] = sci(100.0);
    let mut edited = lines.clone();
    edited[300] = fields.join("\t");
    text = edited.join("\n") + "\n";
    let pixels = file("tracker-px.txt", text.as_bytes());
    let layouts = assert_within_2(&pixels, &[0.9]);
    let AngleFrom::Position { pivot, radius, .. } = layouts[0].angle_from else {
        panic!("{:?}", layouts[0].angle_from)
    };
    assert!(
        (pivot[0] - 640.0).abs() < 2.0 && (pivot[1] - 120.0).abs() < 2.0,
        "{pivot:?}"
    );
    assert!((radius / 400.0 - 0.9).abs() < 0.01, "{radius}");
}

/// Vernier in degrees; PASCO with two runs side by side (the second
/// shorter, padded with empty cells); an IMU logger's lists.
#[test]
fn rotary_sensor_and_imu_exports_read_within_2_percent() {
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    let s = swing(0.3, 0.8, 0.02, 30.0);
    let mut text = String::from(
        "\"Latest: Time (s)\",\"Latest: Angle (°)\",\"Latest: Angular velocity (°/s)\"\n",
    );
    for (t, x) in s.t.iter().zip(&s.x) {
        let a = (x[0] + 0.002 * normal(&mut rng)).to_degrees();
        text.push_str(&format!("{t:.2},{a:.2},{:.2}\n", x[1].to_degrees()));
    }
    assert_within_2(&file("vernier.csv", text.as_bytes()), &[0.3]);
    let (one, two) = (swing(0.6, 0.5, 0.02, 30.0), swing(0.6, 0.2, 0.02, 20.0));
    let comma = |v: f64| format!("{v:.4}").replace('.', ",");
    let mut text = String::from(
        "\u{feff}Time (s) Run #1\tAngle (rad) Run #1\tTime (s) Run #2\tAngle (rad) Run #2\r\n",
    );
    for k in 0..one.t.len() {
        let second = match two.x.get(k) {
            Some(x) => format!("{}\t{}", comma(two.t[k]), comma(x[0])),
            None => "\t".into(),
        };
        text.push_str(&format!(
            "{}\t{}\t{second}\r\n",
            comma(one.t[k]),
            comma(one.x[k][0])
        ));
    }
    let layouts = assert_within_2(&file("capstone.txt", text.as_bytes()), &[0.6, 0.6]);
    assert_eq!(layouts[1].run.as_deref(), Some("Run #2"));
    let imu = swing(0.25, 0.7, 0.004, 25.0);
    let mut text = String::from(
        "Opening phidget object....\nSpatial 302088 Attached!\nwaiting 30 seconds to start...\n",
    );
    for (t, x) in imu.t.iter().zip(&imu.x) {
        let g = [
            0.1 * normal(&mut rng),
            0.1 * normal(&mut rng),
            x[1].to_degrees() + 0.1 * normal(&mut rng),
        ];
        text.push_str(&format!(
            "[{}, 0.03, 0.99, -0.02, {}, {}, {}]\n",
            30.0 + t,
            g[0],
            g[1],
            g[2]
        ));
    }
    let layouts = assert_within_2(&file("imu.txt", text.as_bytes()), &[0.25]);
    assert_eq!(layouts[0].tool, Some("Phidget Spatial logger"));
}

/// A workbook (`.xlsx`) of one sheet holding `csv` (comma-separated,
/// quoted names), numbers as numbers and names as inline strings.
fn workbook(csv: &str) -> Vec<u8> {
    let mut sheet = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\"?>\n<worksheet xmlns=\"http://schemas.openxmlformats.org/spreadsheetml/2006/main\"><sheetData>",
    );
    for (r, line) in csv.lines().enumerate() {
        sheet.push_str(&format!("<row r=\"{}\">", r + 1));
        for (c, field) in line.split(',').enumerate() {
            let at = format!("{}{}", (b'A' + c as u8) as char, r + 1);
            let field = field.trim_matches('"');
            if field.parse::<f64>().is_ok() {
                sheet.push_str(&format!("<c r=\"{at}\"><v>{field}</v></c>"));
            } else {
                sheet.push_str(&format!(
                    "<c r=\"{at}\" t=\"inlineStr\"><is><t>{field}</t></is></c>"
                ));
            }
        }
        sheet.push_str("</row>");
    }
    sheet.push_str("</sheetData></worksheet>");
    let parts = [
        ("[Content_Types].xml", "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\"?>\n<Types xmlns=\"http://schemas.openxmlformats.org/package/2006/content-types\"><Default Extension=\"rels\" ContentType=\"application/vnd.openxmlformats-package.relationships+xml\"/><Default Extension=\"xml\" ContentType=\"application/xml\"/><Override PartName=\"/xl/workbook.xml\" ContentType=\"application/vnd.openxmlformats-officedocument.spreadsheetml.sheet.main+xml\"/><Override PartName=\"/xl/worksheets/sheet1.xml\" ContentType=\"application/vnd.openxmlformats-officedocument.spreadsheetml.worksheet+xml\"/></Types>".to_string()),
        ("_rels/.rels", "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\"?>\n<Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\"><Relationship Id=\"rId1\" Type=\"http://schemas.openxmlformats.org/officeDocument/2006/relationships/officeDocument\" Target=\"xl/workbook.xml\"/></Relationships>".to_string()),
        ("xl/workbook.xml", "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\"?>\n<workbook xmlns=\"http://schemas.openxmlformats.org/spreadsheetml/2006/main\" xmlns:r=\"http://schemas.openxmlformats.org/officeDocument/2006/relationships\"><sheets><sheet name=\"Gyroscope\" sheetId=\"1\" r:id=\"rId1\"/></sheets></workbook>".to_string()),
        ("xl/_rels/workbook.xml.rels", "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\"?>\n<Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\"><Relationship Id=\"rId1\" Type=\"http://schemas.openxmlformats.org/officeDocument/2006/relationships/worksheet\" Target=\"worksheets/sheet1.xml\"/></Relationships>".to_string()),
        ("xl/worksheets/sheet1.xml", sheet),
    ];
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for (name, body) in parts {
        zip.start_file(name, zip::write::SimpleFileOptions::default())
            .unwrap();
        zip.write_all(body.as_bytes()).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

/// A file with no angle, rate or position: the error names each column,
/// what it could be and the option to give.
#[test]
fn an_unknown_layout_is_named_column_by_column() {
    let mut text = String::from("stamp,A,B\n");
    for k in 0..200 {
        let t = k as f64 * 0.02;
        text.push_str(&format!("{t},{},{}\n", 0.3 * (4.0 * t).cos(), 1.5));
    }
    let p = file("unknown.csv", text.as_bytes());
    let e = format!(
        "{:#}",
        import::import_with_layouts(&[p], &ImportOptions::default()).unwrap_err()
    );
    for part in [
        "1 \"stamp\" (increasing, the time?: --time-column 1)",
        "2 \"A\" (swings: an angle, --angle-column 2, or a rate, --rate-column 2)",
        "3 \"B\" (constant)",
        "--angle-column N",
    ] {
        assert!(e.contains(part), "{part:?} not in {e}");
    }
}
