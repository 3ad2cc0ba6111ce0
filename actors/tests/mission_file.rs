//! Mission files: parsing, validation against a catalog, diagnostics with exact positions, and
//! no panic on any input.

use marie_actors::dispatcher::mission::{
    Catalog, Diagnostic, Diagnostics, EndMode, Mission, OpInfo, ParsedMission, StaticCatalog,
};
use marie_vocabulary::property::{ParamDecl, ParamSchema, ParamType, Value};
use marie_vocabulary::status::{FlagDecl, StatusFlags};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn missions_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/missions")
}

fn mission_path(name: &str) -> PathBuf {
    missions_dir().join(name)
}

fn read(name: &str) -> String {
    std::fs::read_to_string(mission_path(name)).expect("test mission file")
}

/// The operations of the test missions, thesis ids where the thesis gives them.
fn catalog() -> StaticCatalog {
    StaticCatalog::new([
        OpInfo::new("wall-sensor", 1512, "1.0.0")
            .params(ParamSchema::new(vec![ParamDecl::float("range_m", 2.0)
                .range(0.5, 5.0)
                .unit("m")]))
            .flags(vec![FlagDecl::new("wall-found", "a wall is in range")]),
        OpInfo::new("wall-follower", 1514, "2.0.0")
            .params(ParamSchema::new(vec![
                ParamDecl::float("distance", 0.5).range(0.1, 2.0).unit("m"),
                ParamDecl::choice("mode", &["wall", "corridor"], "wall"),
                ParamDecl::int("serial", 7).read_only(),
                ParamDecl::new(
                    "pose",
                    ParamType::Struct(vec![
                        ParamDecl::float("x", 0.0).range(-10.0, 10.0),
                        ParamDecl::float("y", 0.0),
                    ]),
                    Value::Struct(
                        [("x".to_string(), 0.0.into()), ("y".to_string(), 0.0.into())].into(),
                    ),
                ),
                ParamDecl::new(
                    "gains",
                    ParamType::Array {
                        item: Box::new(ParamDecl::float("item", 1.0).range(0.0, 5.0)),
                        min_len: 1,
                        max_len: 3,
                    },
                    Value::Array(vec![1.0.into()]),
                ),
            ]))
            .flags(vec![
                FlagDecl::new("aligned", "aligned along the wall"),
                FlagDecl::new("wall-lost", "the wall ended"),
            ]),
        OpInfo::new("docking-detector", 1518, "1.1.0")
            .params(ParamSchema::new(vec![
                ParamDecl::float("breadth", 0.8).range(0.1, 5.0),
                ParamDecl::float("depth", 2.8).range(0.1, 10.0),
            ]))
            .flags(vec![FlagDecl::new(
                "spot-found",
                "a docking spot was found",
            )]),
        OpInfo::new("trajectory-controller", 1511, "1.0.0")
            .params(ParamSchema::new(vec![
                ParamDecl::float("speed", 0.2).range(0.0, 1.0)
            ]))
            .flags(vec![
                FlagDecl::new("parked", "arrived at the end of the path"),
                // not in any mission's [flags]: allowed, ignored at run time
                FlagDecl::new("blocked", "the path is blocked"),
            ]),
        OpInfo::new("ultrasonic", 1516, "1.0.0"),
    ])
}

/// `(line, column, message)` of each diagnostic.
fn positions(d: &Diagnostics) -> Vec<(usize, usize, String)> {
    d.iter()
        .map(|d| (d.line, d.column, d.message.clone()))
        .collect()
}

/// Stage 1 must fail; its diagnostics.
fn parse_err(src: &str) -> Vec<(usize, usize, String)> {
    match ParsedMission::parse(src, None) {
        Ok(_) => panic!("expected stage 1 to reject:\n{src}"),
        Err(d) => positions(&d),
    }
}

/// Stage 1 must pass and stage 2 fail; its diagnostics.
fn validate_err(src: &str) -> Vec<(usize, usize, String)> {
    let parsed = ParsedMission::parse(src, None).unwrap_or_else(|d| panic!("stage 1 failed:\n{d}"));
    match parsed.validate(&catalog()) {
        Ok(_) => panic!("expected stage 2 to reject:\n{src}"),
        Err(d) => positions(&d),
    }
}

/// Assert exactly one diagnostic, at `line:column`, whose message contains every `part`.
#[track_caller]
fn assert_one(diags: &[(usize, usize, String)], line: usize, column: usize, parts: &[&str]) {
    assert_eq!(diags.len(), 1, "expected one diagnostic, got {diags:#?}");
    let (l, c, msg) = &diags[0];
    assert_eq!((*l, *c), (line, column), "position of {msg:?}");
    for p in parts {
        assert!(msg.contains(p), "{msg:?} should contain {p:?}");
    }
}

const HEAD: &str = "[mission]\nname = \"t\"\n\n";

// ---------------------------------------------------------------------------------------------
// A valid mission

#[test]
fn valid_mission_parses_and_validates_into_the_expected_model() {
    let path = mission_path("docking.toml");
    let m = Mission::load(&path, &catalog()).unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(m.name, "docking");
    assert_eq!(
        m.description,
        "find the wall, follow it to a docking spot, park in it"
    );
    assert_eq!(m.path.as_deref(), Some(path.as_path()));
    let flags: BTreeMap<String, u8> = [
        ("powered", 0),
        ("wall-found", 1),
        ("spot-found", 2),
        ("parked", 5),
    ]
    .into_iter()
    .map(|(n, b)| (n.to_string(), b))
    .collect();
    assert_eq!(m.flags, flags);
    assert_eq!(m.initial, StatusFlags(0b1));
    assert_eq!(m.success, StatusFlags(1 << 5));
    assert_eq!(m.deadline, Some(Duration::from_secs(120)));
    assert_eq!(m.actions.len(), 3);

    let find = &m.actions[0];
    assert_eq!(find.name, "find-wall");
    assert_eq!(find.when, StatusFlags(0b1));
    assert_eq!(find.deadline, Duration::from_secs_f64(20.5));
    assert_eq!(find.end_mode, EndMode::Any);
    // ends_on defaults to every operation, in file order
    assert_eq!(find.ends_on, ["ultrasonic", "1512"]);
    assert_eq!(find.ops.len(), 2);
    assert_eq!(
        (
            find.ops[0].key.as_str(),
            find.ops[0].name.as_str(),
            find.ops[0].id
        ),
        ("ultrasonic", "ultrasonic", 1516)
    );
    assert!(find.ops[0].params.is_empty());
    // an operation by id: key as written, canonical name after validation
    let sensor = find.op("1512").expect("op by id");
    assert_eq!((sensor.name.as_str(), sensor.id), ("wall-sensor", 1512));
    // an int given for a float parameter becomes a float
    assert_eq!(sensor.params["range_m"], Value::Float(3.0));

    let follow = &m.actions[1];
    assert_eq!(follow.when, StatusFlags(0b11));
    assert_eq!(follow.ends_on, ["docking-detector"]);
    assert!(follow.ends_on("docking-detector") && !follow.ends_on("wall-follower"));
    assert_eq!(follow.deadline, Duration::from_secs(30), "default deadline");
    let wf = follow.op("wall-follower").expect("wall-follower");
    assert_eq!(wf.params["distance"], Value::Float(1.0));
    assert_eq!(wf.params["mode"], Value::Text("corridor".into()));
    // a struct value is completed with the declared defaults of its omitted fields
    assert_eq!(
        wf.params["pose"],
        Value::Struct(
            [
                ("x".to_string(), Value::Float(1.0)),
                ("y".to_string(), Value::Float(0.0))
            ]
            .into()
        )
    );
    assert_eq!(
        wf.params["gains"],
        Value::Array(vec![Value::Float(1.0), Value::Float(2.5)])
    );
    // omitted parameters are not filled in: the dispatcher keeps the declared defaults
    assert!(!wf.params.contains_key("serial"));
    assert_eq!(wf.params.len(), 4);
    assert_eq!(
        follow.op("docking-detector").map(|o| o.params.len()),
        Some(2)
    );

    let park = &m.actions[2];
    assert_eq!(park.when, StatusFlags(0b100));
    assert_eq!(park.end_mode, EndMode::All);
    assert_eq!(park.ends_on, ["trajectory-controller", "ultrasonic"]);

    assert_eq!(
        m.ops().collect::<Vec<_>>(),
        [
            "ultrasonic",
            "1512",
            "wall-follower",
            "docking-detector",
            "trajectory-controller"
        ]
    );
    assert_eq!(
        m.operation_names(),
        [
            "ultrasonic",
            "wall-sensor",
            "wall-follower",
            "docking-detector",
            "trajectory-controller"
        ]
    );
    assert_eq!(m.flag_name(5), Some("parked"));
    assert_eq!(m.flag_name(3), None);
    assert_eq!(
        m.flags_to_names(StatusFlags(0b10_0010_0101)),
        ["powered", "spot-found", "parked", "#9"]
    );
}

#[test]
fn parsed_mission_lists_the_keys_a_catalog_must_answer() {
    let parsed =
        ParsedMission::parse(&read("docking.toml"), None).unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(parsed.name(), "docking");
    assert_eq!(parsed.flags().get("parked"), Some(&5));
    assert_eq!(
        parsed.ops().collect::<Vec<_>>(),
        [
            "ultrasonic",
            "1512",
            "wall-follower",
            "docking-detector",
            "trajectory-controller"
        ]
    );
    // a catalog keyed by name also resolves ids
    let by_name: BTreeMap<String, OpInfo> = catalog()
        .iter()
        .map(|o| (o.name.clone(), o.clone()))
        .collect();
    assert_eq!(
        by_name.operation("1512").map(|o| o.name),
        Some("wall-sensor".into())
    );
    let m = parsed.validate(&by_name).unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(m.actions[0].ops[1].name, "wall-sensor");
    // a catalog behind a trait object works too
    let dynamic: &dyn Catalog = &by_name;
    assert!(parsed.validate(dynamic).is_ok());
}

#[test]
fn minimal_mission_uses_the_defaults() {
    let src = "[mission]\nname = \"m\"\n[[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n";
    let m = ParsedMission::parse(src, None)
        .and_then(|p| p.validate(&catalog()))
        .unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(m.description, "");
    assert!(m.flags.is_empty() && m.initial.is_empty() && m.success.is_empty());
    assert_eq!(m.deadline, None);
    assert_eq!(m.actions[0].when, StatusFlags::EMPTY);
    assert_eq!(m.actions[0].ends_on, ["ultrasonic"]);
    assert_eq!(m.actions[0].end_mode, EndMode::Any);
    assert_eq!(m.actions[0].deadline, Duration::from_secs(30));
    assert_eq!(m.path, None);
}

// ---------------------------------------------------------------------------------------------
// Stage 1: syntax and structure

#[test]
fn syntax_error_has_its_position() {
    let d = parse_err("[mission]\nname = \"demo\n");
    assert_one(&d, 2, 13, &["syntax error", "string"]);
    let d = parse_err("[mission]\nname = \"a\"\nname = \"b\"\n");
    assert_one(&d, 3, 1, &["syntax error: duplicate key"]);
}

#[test]
fn missing_mission_table_and_name() {
    let d = parse_err("[[action]]\nname = \"a\"\n[action.ops.x]\n");
    assert_one(&d, 1, 1, &["missing table `[mission]`"]);
    let d = parse_err(
        "# header\n[mission]\ndescription = \"no name\"\n[[action]]\nname = \"a\"\n[action.ops.x]\n",
    );
    assert_one(&d, 2, 1, &["missing key `name` in `[mission]`", "string"]);
    let d = parse_err("[mission]\nname = \"\"\n[[action]]\nname = \"a\"\n[action.ops.x]\n");
    assert_one(&d, 2, 8, &["`mission.name` must not be empty"]);
}

#[test]
fn wrong_types_name_the_field_and_what_was_expected() {
    let d = parse_err("[mission]\nname = 5\n[[action]]\nname = \"a\"\n[action.ops.x]\n");
    assert_one(
        &d,
        2,
        8,
        &["expected a string for `mission.name`, found integer"],
    );
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\nwhen = \"ready\"\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        6,
        8,
        &["expected an array of strings for `action.when`, found string"],
    );
    let d = parse_err(&format!(
        "{HEAD}[flags]\nready = 0\n[[action]]\nname = \"a\"\nwhen = [\"ready\", 3]\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        8,
        18,
        &["expected a string in `action.when`, found integer"],
    );
}

#[test]
fn unknown_keys_are_reported_at_the_key_with_the_accepted_ones() {
    let d = parse_err(&format!(
        "{HEAD}[mision]\nname = \"x\"\n[[action]]\nname = \"a\"\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        4,
        2,
        &[
            "unknown key `mision`",
            "expected one of: mission, flags, action",
        ],
    );
    let d = parse_err(
        "[mission]\nname = \"t\"\n  nmae = 1\n[[action]]\nname = \"a\"\n[action.ops.x]\n",
    );
    assert_one(
        &d,
        3,
        3,
        &[
            "unknown key `nmae` in `[mission]`",
            "expected one of: name, description, success, initial, deadline_s, rebind_deadline_s, world",
        ],
    );
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\ndedline_s = 3\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        6,
        1,
        &[
            "unknown key `dedline_s` in `[[action]]`",
            "name, when, ends_on, end_mode, deadline_s, ops",
        ],
    );
}

#[test]
fn flag_bits_must_be_in_range_and_unique() {
    let d = parse_err(&format!(
        "{HEAD}[flags]\nok = 31\ntoo-high = 32\n[[action]]\nname = \"a\"\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        6,
        12,
        &["bit 32 of flag `too-high` is out of range", "0..=31"],
    );
    let d = parse_err(&format!(
        "{HEAD}[flags]\nneg = -1\n[[action]]\nname = \"a\"\n[action.ops.x]\n"
    ));
    assert_one(&d, 5, 7, &["bit -1 of flag `neg` is out of range"]);
    let d = parse_err(&format!(
        "{HEAD}[flags]\nnot-a-bit = \"1\"\n[[action]]\nname = \"a\"\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        5,
        13,
        &["expected a bit number 0..=31 for flag `not-a-bit`, found string"],
    );
    // the later flag in the file is the one reported, whatever the names' order
    let d = parse_err(&format!(
        "{HEAD}[flags]\nzeta = 4\nalpha = 4\n[[action]]\nname = \"a\"\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        6,
        9,
        &["bit 4 of flag `alpha` is already used by flag `zeta`"],
    );
}

#[test]
fn unknown_flag_names_list_the_declared_ones() {
    let d = parse_err(
        "[mission]\nname = \"t\"\nsuccess = [\"done\", \"dnoe\"]\n\n[flags]\ndone = 0\nready = 1\n\
         [[action]]\nname = \"a\"\n[action.ops.x]\n",
    );
    assert_one(
        &d,
        3,
        20,
        &["unknown flag `dnoe` in `mission.success` (expected one of: done, ready)"],
    );
    let d = parse_err(
        "[mission]\nname = \"t\"\ninitial = [\"on\"]\n[[action]]\nname = \"a\"\n[action.ops.x]\n",
    );
    assert_one(
        &d,
        3,
        12,
        &[
            "unknown flag `on` in `mission.initial`",
            "no flags are declared",
        ],
    );
    let d = parse_err(&format!(
        "{HEAD}[flags]\nready = 1\n[[action]]\nname = \"a\"\nwhen = [ \"redy\" ]\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        8,
        10,
        &["unknown flag `redy` in `action.when` (expected one of: ready)"],
    );
}

#[test]
fn duplicate_action_names_point_at_the_first_use() {
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.x]\n[[action]]\nname = \"a\"\n[action.ops.y]\n"
    ));
    assert_one(&d, 8, 8, &["duplicate action name `a` (first used at 5:8"]);
}

#[test]
fn ends_on_must_name_operations_of_the_action() {
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\nends_on = [\"x\", \"z\"]\n[action.ops.x]\n[action.ops.y]\n"
    ));
    assert_one(
        &d,
        6,
        17,
        &["unknown operation `z` in `action.ends_on` (expected one of the action's operations: x, y)"],
    );
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\nends_on = []\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        6,
        11,
        &["`action.ends_on` must name at least one operation"],
    );
}

#[test]
fn end_mode_is_any_or_all() {
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\nend_mode = \"some\"\n[action.ops.x]\n"
    ));
    assert_one(
        &d,
        6,
        12,
        &["expected \"any\" or \"all\" for `action.end_mode`, found \"some\""],
    );
}

#[test]
fn an_action_needs_operations_and_a_mission_needs_actions() {
    let d = parse_err(&format!("{HEAD}[[action]]\nname = \"a\"\nwhen = []\n"));
    assert_one(
        &d,
        4,
        1,
        &["action `a` has no operations", "[action.ops.<operation>]"],
    );
    let d = parse_err(&format!("{HEAD}[[action]]\nname = \"a\"\nops = {{}}\n"));
    assert_one(&d, 6, 7, &["action `a` has no operations"]);
    let d = parse_err("\n[mission]\nname = \"t\"\n");
    assert_one(
        &d,
        2,
        1,
        &["the mission has no actions", "at least one `[[action]]`"],
    );
    let d = parse_err(&format!("{HEAD}[action]\nname = \"a\"\n"));
    assert_one(
        &d,
        4,
        1,
        &["expected an array of tables `[[action]]` for `action`, found table"],
    );
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops]\nx = 5\n"
    ));
    assert_one(
        &d,
        7,
        5,
        &[
            "expected a table of parameters for operation `x`",
            "found integer",
        ],
    );
}

#[test]
fn deadlines_must_be_positive_finite_and_at_most_a_day() {
    for (value, col, part) in [
        (
            "0",
            14,
            "must be a positive, finite number of seconds, found 0",
        ),
        ("-1.5", 14, "found -1.5"),
        ("nan", 14, "found nan"),
        ("inf", 14, "found inf"),
        (
            "\"10\"",
            14,
            "expected a number of seconds for `action.deadline_s`, found string",
        ),
        ("1e300", 14, "more than a mission may wait (86400 s, a day)"),
        ("86401", 14, "more than a mission may wait (86400 s, a day)"),
    ] {
        let d = parse_err(&format!(
            "{HEAD}[[action]]\nname = \"a\"\ndeadline_s = {value}\n[action.ops.x]\n"
        ));
        assert_one(&d, 6, col, &[part]);
        if !part.starts_with("expected") {
            assert!(d[0].2.contains("`action.deadline_s`"), "{:?}", d[0].2);
        }
    }
    let d = parse_err(
        "[mission]\nname = \"t\"\ndeadline_s = -60\n[[action]]\nname = \"a\"\n[action.ops.x]\n",
    );
    assert_one(
        &d,
        3,
        14,
        &["`mission.deadline_s` must be a positive, finite number of seconds, found -60"],
    );
}

#[test]
fn datetime_parameters_have_no_parameter_type() {
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.x]\nat = 1979-05-27T07:32:00Z\nlist = [1, 1979-05-27]\n"
    ));
    assert_eq!(d.len(), 2, "{d:#?}");
    assert_eq!((d[0].0, d[0].1), (7, 6));
    assert!(
        d[0].2.contains("parameter `at` of operation `x`"),
        "{}",
        d[0].2
    );
    assert!(d[0].2.contains("datetime"), "{}", d[0].2);
    assert_eq!((d[1].0, d[1].1), (8, 12));
    assert!(
        d[1].2.contains("parameter `list[1]` of operation `x`"),
        "{}",
        d[1].2
    );
}

#[test]
fn integers_out_of_range_are_reported() {
    let d = parse_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.x]\nbig = 99999999999999999999\n"
    ));
    assert_one(&d, 7, 7, &["integer 99999999999999999999 is out of range"]);
}

#[test]
fn all_structure_errors_of_a_file_are_reported_in_order() {
    let path = mission_path("structure_errors.toml");
    let d = ParsedMission::parse_file(&path).expect_err("broken mission");
    let got: Vec<(usize, usize)> = d.iter().map(|d| (d.line, d.column)).collect();
    assert_eq!(
        got,
        [
            (3, 1),   // unknown key `sucess`
            (4, 14),  // negative deadline
            (8, 14),  // bit 0 used twice
            (9, 10),  // bit 32
            (13, 9),  // unknown flag `powerd`
            (14, 12), // end_mode "first"
            (16, 11), // datetime parameter
            (19, 8),  // duplicate action name
            (20, 12), // ends_on names an operation not in the action
            (23, 1),  // action without operations
            (25, 14), // deadline of the wrong type
        ],
        "{d}"
    );
    let file = path.display().to_string();
    assert!(d.iter().all(|x| x.path == file));
    let text = d.to_string();
    assert_eq!(text.lines().count(), 11);
    assert!(
        text.lines()
            .next()
            .is_some_and(|l| l.starts_with(&format!("{file}:3:1: unknown key `sucess`"))),
        "{text}"
    );
    assert!(text.contains(
        "unknown flag `powerd` in `action.when` (expected one of: parked, powered, wall-found)"
    ));
}

// ---------------------------------------------------------------------------------------------
// Stage 2: against the catalog

#[test]
fn unknown_operation_lists_the_available_ones() {
    let d = validate_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.ultrasonic]\n[action.ops.wal-follower]\n"
    ));
    assert_one(
        &d,
        7,
        13,
        &["unknown operation `wal-follower` (available: docking-detector, trajectory-controller, ultrasonic, wall-follower, wall-sensor)"],
    );
    let d = validate_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.\"9999\"]\n"
    ));
    assert_one(&d, 6, 13, &["unknown operation `9999`"]);
}

#[test]
fn unknown_parameter_lists_the_declared_ones() {
    let d = validate_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-follower]\ndistnce = 0.5\n"
    ));
    assert_one(
        &d,
        7,
        1,
        &["unknown parameter `distnce` of operation `wall-follower` (expected one of: distance, mode, serial, pose, gains)"],
    );
    let d = validate_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.ultrasonic]\ngain = 2\n"
    ));
    assert_one(
        &d,
        7,
        1,
        &["unknown parameter `gain` of operation `ultrasonic` (operation `ultrasonic` has no parameters)"],
    );
}

#[test]
fn parameter_values_are_checked_with_the_reason_at_the_value() {
    let src =
        format!("{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-follower]\ndistance = \"far\"\n");
    assert_one(
        &validate_err(&src),
        7,
        12,
        &["invalid value for parameter `distance` of operation `wall-follower`: expected float, got text"],
    );
    let src = format!("{HEAD}[[action]]\nname = \"a\"\n[action.ops.1514]\ndistance = 3\n");
    assert_one(
        &validate_err(&src),
        7,
        12,
        &["parameter `distance` of operation `wall-follower`: 3 is out of range [0.1, 2]"],
    );
    let src =
        format!("{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-follower]\nmode = \"hall\"\n");
    assert_one(
        &validate_err(&src),
        7,
        8,
        &["\"hall\" is not one of wall|corridor"],
    );
    // nested values: the position of the offending field or element
    let src = format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-follower]\npose = {{ y = 1, x = 11 }}\n"
    );
    assert_one(
        &validate_err(&src),
        7,
        21,
        &["parameter `pose` of operation `wall-follower`: `pose.x`: 11 is out of range [-10, 10]"],
    );
    let src =
        format!("{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-follower]\ngains = [1, 9]\n");
    assert_one(
        &validate_err(&src),
        7,
        13,
        &["`gains[1]`: 9 is out of range [0, 5]"],
    );
    let src = format!("{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-follower]\npose.z = 1\n");
    assert_one(&validate_err(&src), 7, 10, &["`pose.z`: unknown field"]);
}

#[test]
fn read_only_parameters_cannot_be_set_by_a_mission() {
    let d = validate_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-follower]\n  serial = 3\n"
    ));
    assert_one(
        &d,
        7,
        3,
        &["parameter `serial` of operation `wall-follower` is read-only"],
    );
}

#[test]
fn flags_never_raised_are_reported() {
    let src = "[mission]\nname = \"t\"\nsuccess = [\"parked\", \"aligned\"]\ninitial = [\"go\"]\n\
               [flags]\ngo = 0\nparked = 1\naligned = 2\nspot-found = 3\n\
               [[action]]\nname = \"a\"\nwhen = [\"go\", \"spot-found\"]\n[action.ops.trajectory-controller]\n";
    let d = validate_err(src);
    assert_eq!(d.len(), 2, "{d:#?}");
    assert_eq!((d[0].0, d[0].1), (3, 22));
    assert!(d[0]
        .2
        .starts_with("flag `aligned` is never raised by any operation of this mission"));
    assert!(
        d[0].2
            .contains("needed by `mission.success`; they raise: parked"),
        "{}",
        d[0].2
    );
    assert_eq!((d[1].0, d[1].1), (12, 15));
    assert!(
        d[1].2.contains("flag `spot-found` is never raised"),
        "{}",
        d[1].2
    );
    assert!(d[1].2.contains("`action.when`"), "{}", d[1].2);
    // a flag raised by an operation of *another* action is fine, as is an initial one
    let ok = src.replace(
        "[action.ops.trajectory-controller]\n",
        "[action.ops.trajectory-controller]\n[[action]]\nname = \"b\"\n\
         [action.ops.docking-detector]\n[action.ops.wall-follower]\n",
    );
    assert!(ParsedMission::parse(&ok, None)
        .and_then(|p| p.validate(&catalog()))
        .is_ok());
}

#[test]
fn unknown_operations_suppress_the_flag_check() {
    // `sonar` is unknown: whether it would raise `echo` is unknown too, so only it is reported.
    let d = validate_err(
        "[mission]\nname = \"t\"\nsuccess = [\"echo\"]\n[flags]\necho = 0\n\
         [[action]]\nname = \"a\"\n[action.ops.sonar]\n",
    );
    assert_one(&d, 8, 13, &["unknown operation `sonar`"]);
}

#[test]
fn one_operation_twice_in_an_action_is_rejected() {
    let d = validate_err(&format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-sensor]\n[action.ops.\"1512\"]\n"
    ));
    // keys are visited in file order: the id comes second
    assert_one(
        &d,
        7,
        13,
        &["operation `wall-sensor` appears twice in action `a` (as `wall-sensor` and `1512`"],
    );
}

#[test]
fn all_catalog_errors_of_a_file_are_reported_in_order() {
    let path = mission_path("catalog_errors.toml");
    let d = Mission::load(&path, &catalog()).expect_err("typos");
    let got: Vec<(usize, usize, &str)> = d
        .iter()
        .map(|d| (d.line, d.column, d.message.as_str()))
        .collect();
    assert_eq!(got.len(), 7, "{d}");
    let expected: [(usize, usize, &str); 7] = [
        (14, 1, "unknown parameter `distnce`"),
        (15, 8, "\"hall\" is not one of wall|corridor"),
        (16, 1, "`serial` of operation `wall-follower` is read-only"),
        (17, 14, "`pose.x`: 11 is out of range"),
        (18, 13, "`gains[1]`: 9 is out of range"),
        (20, 13, "appears twice in action `follow`"),
        (22, 13, "unknown operation `sonar`"),
    ];
    for ((l, c, msg), (el, ec, part)) in got.iter().zip(expected) {
        assert_eq!((*l, *c), (el, ec), "{msg}");
        assert!(msg.contains(part), "{msg:?} should contain {part:?}");
    }
}

#[test]
fn three_errors_render_one_per_line_with_file_line_column() {
    let path = mission_path("three_errors.toml");
    let d = Mission::load(&path, &catalog()).expect_err("three errors");
    let file = path.display();
    let expected = format!(
        "{file}:7:11: bit 3 of flag `aligned` is already used by flag `in-corner` (each flag needs its own bit)\n\
         {file}:11:9: unknown flag `wall-fuond` in `action.when` (expected one of: aligned, in-corner)\n\
         {file}:12:1: unknown key `dedline_s` in `[[action]]` (expected one of: name, when, ends_on, end_mode, deadline_s, ops, retry, timeout_s, on_failure, while, unless)"
    );
    assert_eq!(d.to_string(), expected);
    // Diagnostics is an std error
    let e: Box<dyn std::error::Error> = Box::new(d);
    assert_eq!(e.to_string().lines().count(), 3);
}

// ---------------------------------------------------------------------------------------------
// Files

#[test]
fn unreadable_file_is_one_diagnostic_at_the_start() {
    let path = missions_dir().join("does-not-exist.toml");
    let d = Mission::load(&path, &catalog()).expect_err("no such file");
    assert_eq!(d.len(), 1);
    let Diagnostic {
        path: p,
        line,
        column,
        message,
    } = &d.0[0];
    assert_eq!(
        (p.as_str(), *line, *column),
        (path.display().to_string().as_str(), 1, 1)
    );
    assert!(message.contains("does-not-exist.toml"), "{message}");
    assert!(message.contains("cannot read mission file"), "{message}");
}

#[test]
fn non_utf8_file_is_reported_at_the_first_bad_byte() {
    let path = std::env::temp_dir().join(format!("marie-mission-{}.toml", std::process::id()));
    std::fs::write(&path, b"[mission]\nname = \"caf\xe9\"\n").expect("write temp file");
    let d = ParsedMission::parse_file(&path).expect_err("not UTF-8");
    let _ = std::fs::remove_file(&path);
    assert_eq!(d.len(), 1);
    assert_eq!((d.0[0].line, d.0[0].column), (2, 12));
    assert!(d.0[0].message.contains("not valid UTF-8"));
}

// ---------------------------------------------------------------------------------------------
// Never a panic

/// A tiny linear congruential generator (Knuth's MMIX constants): fixed seed, no dependency.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        self.0 >> 33
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Parse and (when that succeeds) validate; a panic fails the test with the input.
fn must_not_panic(src: &str, catalog: &StaticCatalog) -> Result<(), Diagnostics> {
    let run = || -> Result<(), Diagnostics> {
        let parsed: ParsedMission = ParsedMission::parse(src, None)?;
        let _ = parsed.ops().count();
        let m = parsed.validate(catalog)?;
        let _ = m.flags_to_names(StatusFlags(u32::MAX));
        Ok(())
    };
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(run)) {
        Ok(r) => {
            if let Err(d) = &r {
                assert!(!d.is_empty(), "an error with no diagnostic for {src:?}");
                assert!(
                    d.iter().all(|x| x.line >= 1 && x.column >= 1),
                    "bad position for {src:?}: {d}"
                );
            }
            r
        }
        Err(_) => panic!("panicked on input:\n{src:?}"),
    }
}

#[test]
fn no_panic_on_truncated_or_garbled_missions() {
    let catalog = catalog();
    let mut sources = vec![read("docking.toml")];
    for name in [
        "structure_errors.toml",
        "catalog_errors.toml",
        "three_errors.toml",
    ] {
        sources.push(read(name));
    }
    // every prefix of every file
    let mut ok = 0;
    for src in &sources {
        for end in (0..=src.len()).filter(|i| src.is_char_boundary(*i)) {
            if must_not_panic(&src[..end], &catalog).is_ok() {
                ok += 1;
            }
        }
    }
    assert!(
        ok > 0,
        "some prefixes of the valid mission are valid missions"
    );

    // random mutations with a fixed seed: byte flips, TOML punctuation, deletions, duplications
    let valid = sources[0].as_bytes().to_vec();
    let punctuation = b"[]{}\"'=.,#\n -+0123456789_xe:TZ\\";
    let mut rng = Lcg(0x6d61_7269_6521);
    for _ in 0..3000 {
        let mut bytes = valid.clone();
        for _ in 0..1 + rng.below(4) {
            let len = bytes.len();
            let i = rng.below(len);
            match rng.below(5) {
                0 => bytes[i] ^= 1 << rng.below(8),
                1 => bytes[i] = punctuation[rng.below(punctuation.len())],
                2 => {
                    let n = rng.below(16).min(len - i);
                    bytes.drain(i..i + n);
                }
                3 => {
                    let n = rng.below(32).min(len - i);
                    let copy: Vec<u8> = bytes[i..i + n].to_vec();
                    let at = rng.below(len);
                    bytes.splice(at..at, copy);
                }
                _ => bytes.insert(i, punctuation[rng.below(punctuation.len())]),
            }
        }
        let src = String::from_utf8_lossy(&bytes);
        let _ = must_not_panic(&src, &catalog);
    }
}

#[test]
fn no_panic_on_pathological_inputs() {
    let catalog = catalog();
    let deep_array = format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.x]\np = {}1{}\n",
        "[".repeat(5000),
        "]".repeat(5000)
    );
    let deep_table = format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.x]\np = {}1{}\n",
        "{a = ".repeat(5000),
        "}".repeat(5000)
    );
    for src in [
        "",
        "\u{feff}",
        "\0",
        "[mission",
        "[[mission]]",
        "mission = 5\naction = 5\nflags = 5",
        "[mission]\nname = \"t\"\naction = [1, \"x\", {}]",
        "[mission]\nname = \"t\"\n[[action]]\nname = \"a\"\nops = []",
        "[mission]\nname = \"t\"\n[[action]]\nname = \"a\"\n[action.ops.\"\"]\n",
        "[mission]\nname = \"t\"\n[flags]\n\"\" = 1\nx = 0x7fffffffffffffff\ny = 0b11\n[[action]]\nname = \"a\"\n[action.ops.x]\n",
        "[mission]\nname = \"é\u{301}\"\n[[action]]\nname = \"\u{1F916}\"\nwhen = [\"\u{1F916}\"]\n[action.ops.\"\u{1F916}\"]\n",
        "[mission]\nname = \"t\"\ndeadline_s = 1e-300\n[[action]]\nname = \"a\"\ndeadline_s = -inf\n[action.ops.ultrasonic]\n",
        &deep_array,
        &deep_table,
    ] {
        assert!(must_not_panic(src, &catalog).is_err(), "{src:?} should be rejected");
    }
}

#[test]
fn large_parameter_arrays_are_fine() {
    // every value's position is recorded; lookups must not rescan the file per value
    let items = vec!["1.5"; 50_000].join(", ");
    let src = format!(
        "{HEAD}[[action]]\nname = \"a\"\n[action.ops.wall-follower]\ngains = [{items}, 7]\n"
    );
    let d = validate_err(&src);
    // the array is too long; its length is checked before the elements
    assert_one(
        &d,
        7,
        9,
        &["`gains` of operation `wall-follower`: length 50001"],
    );
}

#[test]
fn the_mission_names_its_world_relative_to_its_own_file() {
    let body = "[mission]\nname = \"m\"\nworld = \"../worlds/lab.toml\"\n\
                [[action]]\nname = \"a\"\n[action.ops.wall-sensor]\n";
    let file = Path::new("some/dir/m.toml");
    let parsed = ParsedMission::parse(body, Some(file)).unwrap_or_else(|d| panic!("{d}"));
    let expected = Path::new("some/dir").join("../worlds/lab.toml");
    assert_eq!(parsed.world(), Some(expected.as_path()));
    let mission = parsed
        .validate(&catalog())
        .unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(mission.world.as_deref(), Some(expected.as_path()));

    // an absolute path stays as it is; without a file the path is kept as written
    let abs = std::env::temp_dir().join("w.toml");
    let src = body.replace(
        "../worlds/lab.toml",
        &abs.display().to_string().escape_debug().to_string(),
    );
    let parsed = ParsedMission::parse(&src, Some(file)).unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(parsed.world(), Some(abs.as_path()));
    let parsed = ParsedMission::parse(body, None).unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(parsed.world(), Some(Path::new("../worlds/lab.toml")));

    // no world: none
    let parsed = ParsedMission::parse(&body.replace("world = \"../worlds/lab.toml\"\n", ""), None)
        .unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(parsed.world(), None);

    // a mission from older versions (no `world` in its JSON) still reads
    let mut json = serde_json::to_value(&mission).unwrap();
    json.as_object_mut().unwrap().remove("world");
    let old: Mission = serde_json::from_value(json).unwrap();
    assert_eq!(old.world, None);
}

#[test]
fn a_world_that_is_not_a_path_is_reported_at_its_value() {
    let d =
        parse_err("[mission]\nname = \"m\"\nworld = 3\n[[action]]\nname = \"a\"\n[action.ops.x]\n");
    assert_one(
        &d,
        3,
        9,
        &["expected a string for `mission.world`, found integer"],
    );
    let d = parse_err(
        "[mission]\nname = \"m\"\nworld = \" \"\n[[action]]\nname = \"a\"\n[action.ops.x]\n",
    );
    assert_one(&d, 3, 9, &["`mission.world` must not be empty"]);
}
