use super::*;
use armor_module_api::describe::{ParamSpec, ParamType, PortSpec};
use armor_module_api::xml::Located;

const DEMO: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="demo" host="127.0.0.1">
  <module name="counter" type="counter" restart="on-failure" host="127.0.0.1">
    <param name="period_secs" value="0.05"/>
  </module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#;

fn port(name: &str, data_type: &str) -> PortSpec {
    PortSpec {
        name: name.into(),
        data_type: data_type.into(),
        doc: String::new(),
    }
}

fn descriptions() -> BTreeMap<String, ModuleDescription> {
    let mut counter = ModuleDescription::new("counter", "counts");
    counter.outputs.push(port("count", "Counter"));
    counter.inputs.push(port("reset", "Counter"));
    counter
        .params
        .push(ParamSpec::new("period_secs", ParamType::Float, "").default("0.1"));
    counter
        .params
        .push(ParamSpec::new("limit", ParamType::Int, "").default("10"));
    let mut checker = ModuleDescription::new("checker", "checks");
    checker.inputs.push(port("input", "Counter"));
    let mut nav = ModuleDescription::new("nav", "navigates");
    nav.inputs.push(port("scan", "LaserScan"));
    nav.inputs.push(port("odom", "Odometry"));
    nav.outputs.push(port("cmd", "Twist"));
    nav.params
        .push(ParamSpec::new("goal_x", ParamType::Float, ""));
    nav.params
        .push(ParamSpec::new("verbose", ParamType::Bool, "").default("false"));
    let mut sim = ModuleDescription::new("sim", "simulates");
    sim.inputs.push(port("cmd", "Twist"));
    sim.outputs.push(port("odometry", "Odometry"));
    sim.outputs.push(port("scan", "LaserScan"));
    [counter, checker, nav, sim]
        .into_iter()
        .map(|description| (description.module_type.clone(), description))
        .collect()
}

fn rendered(problems: &[Located]) -> Vec<String> {
    problems.iter().map(ToString::to_string).collect()
}

/// Structural problems of `xml` (none expected: `&[]`).
fn parse_problems(xml: &str, expected: &[&str]) {
    let got = match SystemConfig::parse(xml) {
        Ok(_) => Vec::new(),
        Err(problems) => rendered(&problems),
    };
    assert_eq!(got, expected, "for:\n{xml}");
}

/// Problems of `xml` against [`descriptions`]; `xml` must be structurally valid.
fn check(xml: &str, expected: &[&str]) {
    let system = match SystemConfig::parse(xml) {
        Ok(system) => system,
        Err(problems) => panic!("structural problems: {:?}", rendered(&problems)),
    };
    let got = rendered(&super::check(&system, &descriptions()));
    assert_eq!(got, expected, "for:\n{xml}");
}

/// A system of `modules` (`name:type[:param=value,...]`) and `links` (`from>to`), one
/// element per line starting at line 2.
fn system(modules: &[&str], links: &[&str]) -> String {
    let mut out = String::from("<system name=\"s\">\n");
    for module in modules {
        let mut parts = module.split(':');
        let name = parts.next().unwrap_or_default();
        let module_type = parts.next().unwrap_or_default();
        out.push_str(&format!("<module name=\"{name}\" type=\"{module_type}\">"));
        for param in parts
            .next()
            .into_iter()
            .flat_map(|params| params.split(','))
        {
            let (param, value) = param.split_once('=').unwrap_or((param, ""));
            out.push_str(&format!("<param name=\"{param}\" value=\"{value}\"/>"));
        }
        out.push_str("</module>\n");
    }
    for link in links {
        let (from, to) = link.split_once('>').unwrap_or((link, ""));
        out.push_str(&format!("<link from=\"{from}\" to=\"{to}\"/>\n"));
    }
    out.push_str("</system>\n");
    out
}

#[test]
fn the_demo_parses() {
    let demo = SystemConfig::parse(DEMO).expect("demo is valid");
    assert_eq!(demo.name, "demo");
    assert_eq!(demo.host_or_default(), "127.0.0.1");
    assert_eq!(demo.modules.len(), 2);
    let counter = &demo.modules[0];
    assert_eq!(counter.restart, RestartPolicy::OnFailure);
    assert_eq!(counter.type_pos, Pos { line: 3, col: 26 });
    assert_eq!(counter.params[0].value_pos, Pos { line: 4, col: 31 });
    assert_eq!(demo.modules[1].host, None);
    assert_eq!(demo.links[0].from.to_string(), "counter.count");
    assert_eq!(demo.links[0].to_pos, Pos { line: 7, col: 30 });
    assert!(super::check(&demo, &descriptions()).is_empty());
}

#[test]
fn the_bundled_demo_is_clean() {
    let demo = SystemConfig::parse(include_str!("../../../../missions/demo/system.xml"))
        .unwrap_or_else(|problems| panic!("{:?}", rendered(&problems)));
    assert!(super::check(&demo, &descriptions()).is_empty());
    let counter = demo.bindings("counter", descriptions().get("counter"));
    assert_eq!(
        counter.map(|b| b.params.get("period_secs").cloned()),
        Some(Some("0.1".to_owned()))
    );
}

#[test]
fn restart_policies() {
    for policy in [
        RestartPolicy::Never,
        RestartPolicy::OnFailure,
        RestartPolicy::Always,
    ] {
        assert_eq!(policy.as_str().parse(), Ok(policy));
    }
    assert_eq!(RestartPolicy::default(), RestartPolicy::OnFailure);
}

#[test]
fn structural_problems() {
    // Clean.
    parse_problems(DEMO, &[]);
    parse_problems("<system name=\"empty\"/>", &[]);
    // Truncated and malformed documents.
    parse_problems(
        "<system name=\"s\">\n  <module name=\"a\" type=\"t\">",
        &["2:29: document ends before <module> (line 2) is closed"],
    );
    parse_problems(
        "<system name=\"s\">\n  <module name=\"a\" type=\"t\"></system>",
        &[
            "2:29: malformed XML: ill-formed document: expected `</module>`, but `</system>` was found",
        ],
    );
    parse_problems(
        "<system name=\"s",
        &["1:1: malformed XML: syntax error: tag not closed: `>` not found before end of input"],
    );
    parse_problems("", &["1:1: document has no element"]);
    // Wrong root.
    parse_problems(
        "<module type=\"counter\"/>",
        &["1:1: expected <system> at the top, found <module>"],
    );
    // Unknown elements and attributes, text, all of them sorted.
    parse_problems(
        "<system name=\"s\" color=\"red\">\n  <modul name=\"a\"/>\n  <module name=\"a\" type=\"t\" prio=\"1\">\n    <parameter/>\n    <param name=\"p\" value=\"1\" unit=\"s\"><x/></param>\n  </module>\n  <link from=\"a.b\" to=\"a.c\" via=\"d\">text</link>\n</system>",
        &[
            "1:18: unknown attribute `color` on <system> (expected one of: name, host)",
            "2:3: unknown element <modul> inside <system> (expected one of: host, module, link, subsystem)",
            "3:29: unknown attribute `prio` on <module> (expected one of: name, type, restart, activation, host, may_publish, may_subscribe)",
            "4:5: unknown element <parameter> inside <module> (expected one of: param)",
            "5:31: unknown attribute `unit` on <param> (expected one of: name, value)",
            "5:40: unknown element <x> inside <param> (it has no elements)",
            "7:3: <link> must not contain text (found `text`)",
            "7:29: unknown attribute `via` on <link> (expected one of: from, to, fallback, max_rate_hz)",
        ],
    );
    // Missing and empty required attributes.
    parse_problems(
        "<system>\n<module/>\n<module name=\"\" type=\"t\" host=\"\"><param/></module>\n<link/>\n</system>",
        &[
            "1:1: <system> needs the attribute `name`",
            "2:1: <module> needs the attribute `name`",
            "2:1: <module> needs the attribute `type`",
            "3:9: attribute `name` of <module> must not be empty",
            "3:26: attribute `host` of <module> must not be empty",
            "3:34: <param> needs the attribute `name`",
            "3:34: <param> needs the attribute `value`",
            "4:1: <link> needs the attribute `from`",
            "4:1: <link> needs the attribute `to`",
        ],
    );
    // Names that are not identifiers, bad restart policy, bad endpoints.
    parse_problems(
        "<system name=\"my system\">\n<module name=\"9a\" type=\"a.b\" restart=\"sometimes\">\n<param name=\"-p\" value=\"\"/>\n</module>\n<link from=\"counter\" to=\"a.b.c\"/>\n<link from=\".x\" to=\"a.9\"/>\n<module name=\"c\" type=\"c\" activation=\"lazy\"/>\n</system>",
        &[
            "1:9: name `my system` of <system> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
            "2:9: name `9a` of <module> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
            "2:19: module type `a.b` of <module> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
            "2:30: unknown restart policy `sometimes` (expected never, on-failure or always)",
            "3:8: name `-p` of <param> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
            "5:7: `from` must be MODULE.OUTPUT (two names joined by a dot), not `counter`",
            "5:22: `to` must be MODULE.INPUT (two names joined by a dot), not `a.b.c`",
            "6:7: `from` must be MODULE.OUTPUT (two names joined by a dot), not `.x`",
            "6:17: `to` must be MODULE.INPUT (two names joined by a dot), not `a.9`",
            "7:27: unknown activation `lazy` (expected on-demand, always or explicit)",
        ],
    );
}

#[test]
fn an_empty_string_parameter_value_is_allowed() {
    let system = SystemConfig::parse(
            "<system name=\"s\"><module name=\"a\" type=\"t\"><param name=\"label\" value=\"\"/></module></system>",
        )
        .expect("valid");
    assert_eq!(system.modules[0].params[0].value, "");
}

#[test]
fn fallback_sources_and_the_health_stream() {
    let xml = |links: &str| {
        format!(
            "<system name=\"s\">\n<module name=\"a\" type=\"counter\"/>\n<module name=\"b\" type=\"counter\"/>\n<module name=\"k\" type=\"checker\"/>\n{links}</system>"
        )
    };
    // A source, two fallbacks in any order: the bindings take the source, `sources` all.
    let text = xml(
        "<link from=\"b.count\" to=\"k.input\" fallback=\"2\"/>\n<link from=\"a.count\" to=\"k.input\"/>\n<link from=\"a.count\" to=\"k.input\" fallback=\"1\"/>\n",
    );
    check(&text, &[]);
    let system = SystemConfig::parse(&text).expect("valid");
    let sources: Vec<(String, u32)> = system
        .sources(&Endpoint::new("k", "input"))
        .iter()
        .map(|link| (link.from.to_string(), link.fallback))
        .collect();
    assert_eq!(
        sources,
        [
            ("a.count".to_owned(), 0),
            ("a.count".to_owned(), 1),
            ("b.count".to_owned(), 2)
        ]
    );
    let bindings = system.bindings("k", None).expect("a module");
    assert_eq!(bindings.inputs["input"], "a.count");
    round_trip(&text);
    // Two fallbacks of one rank; a rank that is not one.
    check(
        &xml(
            "<link from=\"a.count\" to=\"k.input\"/>\n<link from=\"b.count\" to=\"k.input\" fallback=\"1\"/>\n<link from=\"a.count\" to=\"k.input\" fallback=\"1\"/>\n",
        ),
        &["7:1: input `k.input` already has `b.count` as fallback 1 (line 6)"],
    );
    parse_problems(
        &xml("<link from=\"a.count\" to=\"k.input\" fallback=\"0\"/>\n"),
        &["5:35: `fallback` is the fallback's rank, 1, 2, …, not `0`"],
    );
    // Fallbacks alone: nothing feeds the input.
    check(
        &xml("<link from=\"b.count\" to=\"k.input\" fallback=\"2\"/>\n"),
        &[
            "5:1: input `k.input` has a fallback but no source: one of its links needs no `fallback`",
        ],
    );
    // The health stream is the runtime's: a `Health` input takes it, a `Counter` one does not.
    check(
        &xml("<link from=\"armor.health\" to=\"k.input\"/>\n"),
        &["5:27: module `k`: input `input` expects Counter but `armor.health` is Health"],
    );
}

#[test]
fn problems_against_descriptions() {
    // Clean: defaults may be left out, a module may feed itself, an output may feed many.
    check(
        &system(
            &[
                "c:counter:period_secs=0.5,limit=3",
                "k:checker",
                "k2:checker",
            ],
            &["c.count>k.input", "c.count>k2.input", "c.count>c.reset"],
        ),
        &[],
    );
    // Duplicate module names and parameters.
    check(
        &system(&["nav:checker", "nav:counter:limit=1,limit=2"], &[]),
        &[
            "3:1: module `nav` is already defined at line 2",
            "3:66: module `nav`: parameter `limit` is already set at line 3",
        ],
    );
    // Unknown module type: no parameter or port checks for it.
    check(
        &system(
            &["nav:navigaton:whatever=1", "k:checker"],
            &["nav.cmd>k.input", "k.nothing>nav.scan"],
        ),
        &[
            "2:20: module `nav`: no module type `navigaton` on the module path (known: checker, counter, nav, sim)",
            "5:7: link from `k.nothing`: module `k` (type `checker`) has no output `nothing` (outputs: none)",
        ],
    );
    // Parameters: unknown, wrong values, missing required.
    check(
        &system(
            &[
                "c:counter:period_secs=fast,speed=2,limit=1.5",
                "n:nav:verbose=yes",
                "k:checker:x=1",
            ],
            &[],
        ),
        &[
            "2:59: module `c`: parameter `period_secs` (float): `fast` is not a finite number",
            "2:73: module `c`: module type `counter` has no parameter `speed` (known: period_secs, limit)",
            "2:124: module `c`: parameter `limit` (int): `1.5` is not a whole number",
            "3:1: module `n`: required parameter `goal_x` is not set",
            "3:51: module `n`: parameter `verbose` (bool): `yes` is not `true` or `false`",
            "4:33: module `k`: module type `checker` has no parameter `x` (known: none)",
        ],
    );
    // Links: unknown modules and ports, wrong directions.
    check(
        &system(
            &["c:counter", "k:checker"],
            &[
                "ghost.count>k.input",
                "c.count>ghost.input",
                "c.cnt>k.inp",
                "k.input>c.count",
            ],
        ),
        &[
            "4:7: link from `ghost.count`: no module `ghost` in this system",
            "5:22: link to `ghost.input`: no module `ghost` in this system",
            "6:7: link from `c.cnt`: module `c` (type `counter`) has no output `cnt` (outputs: count)",
            "6:20: link to `k.inp`: module `k` (type `checker`) has no input `inp` (inputs: input)",
            "7:7: link from `k.input`: `input` is an input of `k`; a link goes from an output to an input",
            "7:22: link to `c.count`: `count` is an output of `c`; a link goes from an output to an input",
        ],
    );
    // Type mismatches and inputs fed twice.
    check(
        &system(
            &["sim:sim", "nav:nav:goal_x=1", "c:counter", "k:checker"],
            &[
                "sim.odometry>nav.scan",
                "sim.scan>nav.scan",
                "c.count>k.input",
                "c.count>k.input",
                "nav.cmd>sim.cmd",
            ],
        ),
        &[
            "6:27: module `nav`: input `scan` expects LaserScan but `sim.odometry` is Odometry",
            "7:23: input `nav.scan` is already fed by `sim.odometry` (line 6); another source is a fallback (fallback=\"1\", \"2\", …)",
            "9:22: input `k.input` is already fed by `c.count` (line 8); another source is a fallback (fallback=\"1\", \"2\", …)",
        ],
    );
}

#[test]
fn a_thousand_modules() {
    let modules: Vec<String> = (0..1000)
        .map(|i| format!("c{i}:counter:period_secs=0.{i}"))
        .chain(std::iter::once("k:checker".to_owned()))
        .collect();
    let links: Vec<String> = (0..1000)
        .map(|i| format!("c{i}.count>c{}.reset", (i + 1) % 1000))
        .collect();
    let modules: Vec<&str> = modules.iter().map(String::as_str).collect();
    let mut links: Vec<&str> = links.iter().map(String::as_str).collect();
    links.push("c0.count>k.input");
    let xml = system(&modules, &links);
    let parsed = SystemConfig::parse(&xml).expect("valid");
    assert_eq!(parsed.modules.len(), 1001);
    assert_eq!(parsed.links.len(), 1001);
    check(&xml, &[]);
}

/// The configuration with every position set to zero.
fn without_positions(mut system: SystemConfig) -> SystemConfig {
    let zero = Pos::default();
    for module in &mut system.modules {
        (module.pos, module.type_pos) = (zero, zero);
        for param in &mut module.params {
            (param.pos, param.value_pos) = (zero, zero);
        }
    }
    for link in &mut system.links {
        (link.pos, link.from_pos, link.to_pos) = (zero, zero, zero);
    }
    fn unplace(subsystem: &mut Subsystem) {
        let zero = Pos::default();
        subsystem.pos = zero;
        for member in &mut subsystem.members {
            member.pos = zero;
        }
        for port in &mut subsystem.ports {
            (port.pos, port.of_pos) = (zero, zero);
        }
        subsystem.subsystems.iter_mut().for_each(unplace);
    }
    system.subsystems.iter_mut().for_each(unplace);
    for host in &mut system.hosts {
        host.pos = zero;
    }
    system
}

/// `xml` parses, and writing it then reading it back gives the same configuration.
fn round_trip(xml: &str) {
    let system = SystemConfig::parse(xml).expect("valid");
    let written = system.to_xml();
    let again = SystemConfig::parse(&written)
        .unwrap_or_else(|problems| panic!("{written}\n{:?}", rendered(&problems)));
    assert_eq!(
        without_positions(again),
        without_positions(system),
        "{written}"
    );
}

#[test]
fn round_trips_through_xml() {
    round_trip(DEMO);
    round_trip("<system name=\"s\"/>");
    round_trip(
        "<system name=\"s\" host=\"::1\">\n<module name=\"a\" type=\"t\" restart=\"never\" activation=\"explicit\"/><module name=\"c\" type=\"t\" activation=\"always\"/>\n<module name=\"b\" type=\"t\" restart=\"always\" host=\"robot-2.local\">\n<param name=\"text\" value=\"&lt;a &amp; 'b' &quot;c&quot;&gt;&#10;&#9;next&#13;\"/>\n<param name=\"empty\" value=\"\"/>\n<param name=\"unicode\" value=\"été → 🤖\"/>\n</module>\n<link from=\"a.x\" to=\"b.y\"/>\n<link from=\"b.y\" to=\"b.z\"/>\n</system>",
    );
    // Values set in code, written then read.
    let mut system = SystemConfig::parse(DEMO).expect("valid");
    system.modules[0].params[0].value = "a\r\nb\t\"c\" <d> & 'e'".into();
    system.host = Some("10.0.0.1".into());
    round_trip(&system.to_xml());
    let again = SystemConfig::parse(&system.to_xml()).expect("valid");
    assert_eq!(again.modules[0].params[0].value, "a\r\nb\t\"c\" <d> & 'e'");
}

/// The bindings of `module` in `xml`, each map rendered as `key=value` joined by spaces:
/// `[inputs, outputs, params]`.
fn bindings(xml: &str, module: &str, with_description: bool, expected: Option<[&str; 3]>) {
    let system = SystemConfig::parse(xml).expect("valid");
    let descriptions = descriptions();
    let description = system
        .module(module)
        .and_then(|instance| descriptions.get(&instance.module_type))
        .filter(|_| with_description);
    let render = |map: &BTreeMap<String, String>| {
        map.iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let got = system.bindings(module, description).map(|b| {
        assert_eq!(
            Some(b.module_type.as_str()),
            system.module(module).map(|m| m.module_type.as_str())
        );
        [render(&b.inputs), render(&b.outputs), render(&b.params)]
    });
    assert_eq!(got, expected.map(|e| e.map(str::to_owned)));
}

#[test]
fn bindings_of_modules() {
    let xml = system(
        &["c:counter:limit=5", "k:checker", "n:nav:goal_x=2", "s:sim"],
        &[
            "c.count>k.input",
            "c.count>c.reset",
            "s.scan>n.scan",
            "s.odometry>n.odom",
            "n.cmd>s.cmd",
        ],
    );
    bindings(
        &xml,
        "c",
        true,
        Some(["reset=c.count", "count=c.count", "limit=5 period_secs=0.1"]),
    );
    bindings(&xml, "k", true, Some(["input=c.count", "", ""]));
    bindings(
        &xml,
        "n",
        true,
        Some([
            "odom=s.odometry scan=s.scan",
            "cmd=n.cmd",
            "goal_x=2 verbose=false",
        ]),
    );
    bindings(
        &xml,
        "s",
        true,
        Some(["cmd=n.cmd", "odometry=s.odometry scan=s.scan", ""]),
    );
    // Without a description: outputs that links use, configured parameters only.
    bindings(
        &xml,
        "c",
        false,
        Some(["reset=c.count", "count=c.count", "limit=5"]),
    );
    bindings(
        &xml,
        "s",
        false,
        Some(["cmd=n.cmd", "odometry=s.odometry scan=s.scan", ""]),
    );
    bindings(&xml, "nobody", true, None);
}

/// A system with two subsystems, one nested.
const GROUPED: &str = r#"<system name="g">
  <module name="sim" type="sim"/>
  <module name="nav" type="nav"><param name="goal_x" value="1"/></module>
  <module name="counter" type="counter"/>
  <module name="checker" type="checker"/>
  <link from="sim.scan" to="nav.scan"/>
  <link from="nav.cmd" to="sim.cmd"/>
  <link from="counter.count" to="checker.input"/>
  <subsystem name="robot">
    <member module="nav"/>
    <subsystem name="body">
      <member module="sim"/>
    </subsystem>
    <port name="scan" of="sim.scan"/>
  </subsystem>
  <subsystem name="counting">
    <member module="counter"/>
    <member module="checker"/>
  </subsystem>
</system>
"#;

#[test]
fn subsystems_parse_nest_and_round_trip() {
    let system = SystemConfig::parse(GROUPED).expect("valid");
    assert_eq!(system.subsystems.len(), 2);
    let robot = system.subsystem("robot").expect("robot");
    assert_eq!(robot.modules(), ["nav", "sim"]);
    assert_eq!(robot.ports[0].of, Endpoint::new("sim", "scan"));
    assert_eq!(system.subsystem_path("sim"), ["robot", "body"]);
    assert_eq!(system.subsystem_path("checker"), ["counting"]);
    assert!(system.subsystem_path("nope").is_empty());
    assert_eq!(system.units("body"), Some(vec!["sim".to_owned()]));
    assert_eq!(system.units("nav"), Some(vec!["nav".to_owned()]));
    assert_eq!(system.units("nothing"), None);
    // Flattened, it is the same modules and links.
    assert_eq!(system.modules.len(), 4);
    assert_eq!(system.links.len(), 3);
    check(GROUPED, &[]);
    round_trip(GROUPED);
    // Written, it is still a subsystem element per group, nested.
    let written = system.to_xml();
    assert!(written.contains("    <subsystem name=\"body\">\n      <member module=\"sim\"/>"));
}

#[test]
fn subsystem_structural_problems_have_positions() {
    parse_problems(
        "<system name=\"s\">\n<subsystem>\n<member/>\n<port name=\"p\" of=\"x\"/>\n<wheel/>\n</subsystem>\n</system>",
        &[
            "2:1: <subsystem> needs the attribute `name`",
            "3:1: <member> needs the attribute `module`",
            "4:16: `of` must be MODULE.PORT (two names joined by a dot), not `x`",
            "5:1: unknown element <wheel> inside <subsystem> (expected one of: member, port, subsystem)",
        ],
    );
}

#[test]
fn subsystem_problems_against_the_system() {
    let xml = r#"<system name="s">
<module name="counter" type="counter"/>
<module name="checker" type="checker"/>
<subsystem name="a"><member module="counter"/><member module="ghost"/>
<port name="out" of="counter.count"/><port name="out" of="counter.reset"/>
<port name="wrong" of="counter.nothing"/><port name="far" of="checker.input"/></subsystem>
<subsystem name="b"><member module="counter"/></subsystem>
<subsystem name="a"><member module="checker"/></subsystem>
<subsystem name="checker"><subsystem name="empty"/></subsystem>
</system>"#;
    check(
        xml,
        &[
            "4:47: subsystem `a`: no module `ghost` in this system (modules: checker, counter)",
            "5:38: subsystem `a`: port `out` is already exposed at line 5",
            "6:20: subsystem `a`: port `wrong` is of `counter.nothing`, but module `counter` (type `counter`) has no port `nothing` (ports: reset, count)",
            "6:59: subsystem `a`: port `far` is of `checker.input`, but module `checker` is not in the subsystem (members: counter, ghost)",
            "7:21: subsystem `b`: module `counter` is already a member of `a` (line 4); a module is in one subsystem at most",
            "8:1: subsystem `a` is already defined at line 4",
            "9:1: subsystem `checker`: a module has that name (line 3); a place names one or the other",
            "9:27: subsystem `empty` has no member (add <member module=\"…\"/>)",
        ],
    );
}

const ROBOT_ON_TWO: &str = "<system name=\"s\" host=\"10.0.0.1\">\n<host name=\"robot1\" address=\"10.0.0.2\"/>\n<host name=\"arm\" address=\"fe80::2\" port=\"7500\"/>\n<module name=\"a\" type=\"t\" host=\"robot1\"/>\n<module name=\"b\" type=\"t\" host=\"10.0.0.9\"/>\n<module name=\"c\" type=\"t\"/>\n<link from=\"a.x\" to=\"c.y\" max_rate_hz=\"2.5\"/>\n<link from=\"c.x\" to=\"a.y\"/>\n</system>";

#[test]
fn modules_are_placed_on_declared_hosts() {
    let system = SystemConfig::parse(ROBOT_ON_TWO).expect("valid");
    assert_eq!(system.hosts.len(), 2);
    assert_eq!(system.hosts[0].daemon_addr(), "10.0.0.2:7410");
    assert_eq!(system.hosts[1].daemon_addr(), "[fe80::2]:7500");
    let [a, b, c] = [0, 1, 2].map(|i| &system.modules[i]);
    assert_eq!(
        system.placement(a).map(|host| host.name.as_str()),
        Some("robot1")
    );
    // A host that names no declaration is an address on the supervisor's machine, as before.
    assert_eq!(system.placement(b), None);
    assert_eq!(system.placement(c), None);
    assert_eq!(system.bind_address(a), "10.0.0.2");
    assert_eq!(system.bind_address(b), "10.0.0.9");
    assert_eq!(system.bind_address(c), "10.0.0.1");
    assert_eq!(system.input_rates("c"), [("y".to_owned(), 2.5)].into());
    assert!(system.input_rates("a").is_empty());
    round_trip(ROBOT_ON_TWO);
}

#[test]
fn bad_hosts_and_rates_are_reported_where_they_are() {
    parse_problems(
        "<system name=\"s\">\n<host name=\"r\" address=\"a\"/><host name=\"r\" address=\"b\"/>\n<host address=\"\" port=\"0\" os=\"linux\"/>\n<link from=\"a.b\" to=\"c.d\" max_rate_hz=\"fast\"/>\n<link from=\"a.b\" to=\"c.e\" max_rate_hz=\"-1\"/>\n</system>",
        &[
            "2:29: host `r` is declared twice",
            "3:1: <host> needs the attribute `name`",
            "3:7: attribute `address` of <host> must not be empty",
            "3:18: `port` is a TCP port, 1 to 65535, not `0`",
            "3:27: unknown attribute `os` on <host> (expected one of: name, address, port)",
            "4:27: `max_rate_hz` is a number of samples a second above 0, not `fast`",
            "5:27: `max_rate_hz` is a number of samples a second above 0, not `-1`",
        ],
    );
}

#[test]
fn a_data_name_has_one_publisher() {
    // A grant of another module's names (`sim.*` to the replayer) is reported where it is
    // written; a grant of names no module of the system serves is the widening it is for.
    check(
        "<system name=\"s\">\n\
         <module name=\"sim\" type=\"sim\"/>\n\
         <module name=\"replay\" type=\"checker\" may_publish=\"sim.* lidar.scan\"/>\n\
         </system>",
        &[
            "3:1: module `replay`: its may_publish covers `sim.odometry`, an output of module `sim`; a data name has one publisher",
            "3:1: module `replay`: its may_publish covers `sim.scan`, an output of module `sim`; a data name has one publisher",
        ],
    );
    check(
        "<system name=\"s\">\n\
         <module name=\"replay\" type=\"checker\" may_publish=\"sim.*\"/>\n\
         </system>",
        &[],
    );
}
