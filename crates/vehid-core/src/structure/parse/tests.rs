use super::*;

fn build(eqs: &[(&str, &str)]) -> Result<(Structure<f64>, Names), StructureError> {
    let mut b = StructureBuilder::new(&["q", "v", "w"], &["tau"]);
    for (s, t) in eqs {
        b = b.equation(s, t);
    }
    b.build()
}

#[test]
fn expands_products_and_evaluates() {
    let (s, names) = build(&[("v", "a*tau - b*(v - w) - c*sign(v - 2*w) - d + 0.5*q")]).unwrap();
    assert_eq!(names.params, ["a", "b", "c", "d"]);
    let (x, z, u) = ([0.3, 1.0, 2.0], [0.0, 7.0, 0.0], [4.0]);
    let mut h = [0.0; 4];
    let y = s.regression(0, &x, &z, &u, &mut h);
    // sign(1 - 4) = -1
    assert_eq!(h, [4.0, -(1.0 - 2.0), 1.0, -1.0]);
    assert_eq!(y, 7.0 - 0.5 * 0.3);
}

#[test]
fn errors_name_the_item_and_the_fix() {
    let e = build(&[("v", "a*tua - b*v")]).unwrap_err();
    assert_eq!(e.item, "equation for v");
    assert!(e.message.contains("misspelled") && e.message.contains("tau"), "{e}");
    let e = build(&[("vv", "a*v")]).unwrap_err();
    assert!(e.message.contains("not a state"), "{e}");
    let e = build(&[("v", "a*v*w")]).unwrap_err();
    assert!(e.message.contains("two variables"), "{e}");
    let e = build(&[("v", "a*v + 2*a*v - b*(3*v)")]).unwrap_err();
    assert!(e.message.contains("'a' and 'b'"), "{e}");
    let e = build(&[("v", "a*v +")]).unwrap_err();
    assert!(e.message.contains("position"), "{e}");
    let e = build(&[("v", "a/b*v")]).unwrap_err();
    assert!(e.message.contains("divide only by numbers"), "{e}");
    let e = build(&[("v", "a*der(v)")]).unwrap_err();
    assert!(e.message.contains("own state's derivative"), "{e}");
    let e = StructureBuilder::new(&["q", "v"], &[]).equation("v", "a*v").parameters(&["a", "b"]).build::<f64>();
    assert!(e.unwrap_err().message.contains("'b' appears in no identified equation"));
    let e = StructureBuilder::new(&["q", "v"], &[]).equation("v", "a*v - b").parameters(&["a"]).build::<f64>();
    assert!(e.unwrap_err().message.contains("declared parameter"));
    let e = StructureBuilder::new(&["q", "v"], &[]).equation("v", "a*v").known("q", "k*v").build::<f64>();
    assert!(e.unwrap_err().message.contains("known equations take no parameters"));
    let e = StructureBuilder::new(&["q", "v"], &[]).equation("v", "3*v").build::<f64>();
    assert!(e.unwrap_err().message.contains("no parameter"));
    let e = StructureBuilder::new(&["q", "1v"], &[]).equation("q", "a*q").build::<f64>();
    assert_eq!(e.unwrap_err().item, "states");
}

#[test]
fn derivatives_order_the_simulation() {
    // v's equation reads der(w): w is computed first whatever the declaration order.
    let (s, _) = StructureBuilder::new(&["q", "v", "w"], &[])
        .equation("v", "-m*der(w) - k*q")
        .equation("w", "-c*w")
        .known("q", "v")
        .build::<f64>()
        .unwrap();
    let mut out = [0.0; 3];
    s.derivative(&[2.0, 3.0, 0.5], &[1.0, 0.0, 4.0], &[], &mut out);
    assert_eq!(out, [0.0, -2.0 * (-0.5 * 4.0) - 3.0 * 1.0, -2.0]);
    let e = StructureBuilder::new(&["v", "w"], &[]).equation("v", "a*der(w)").equation("w", "b*der(v)").build::<f64>();
    assert!(e.unwrap_err().message.contains("loop"));
}

#[test]
fn partition_groups_shared_parameters() {
    let (s, _) = StructureBuilder::new(&["a", "b", "c"], &[])
        .equation("a", "p*a + q*b")
        .equation("b", "r*c")
        .equation("c", "q*c + s")
        .build::<f64>()
        .unwrap();
    let part = s.partition();
    assert_eq!(part.groups, 2);
    assert_eq!(&part.group_of_param[..4], &[0, 0, 1, 0]);
    assert_eq!(&part.local[..4], &[0, 1, 0, 2]);
    assert_eq!(&part.group_of_eq[..3], &[0, 1, 0]);
    assert_eq!(part.largest(), 3);
}

/// Runs `f` on a thread with a 1 MiB stack, half what a spawned thread gets by default:
/// a parser that recursed once per level of a 10,000-byte text would overflow it (about
/// 1.3 KiB per level at the test profile's `opt-level = 1`).
fn on_small_stack<R: Send + 'static>(f: impl FnOnce() -> R + Send + 'static) -> R {
    std::thread::Builder::new().stack_size(1 << 20).spawn(f).unwrap().join().unwrap()
}

fn one_state(text: String) -> Result<(Structure<f64>, Names), StructureError> {
    StructureBuilder::new(&["x"], &[]).equation("x", &text).build::<f64>()
}

fn assert_limit(r: Result<(Structure<f64>, Names), StructureError>, item: &str, words: &str) {
    let e = r.unwrap_err();
    assert_eq!(e.item, item, "{e}");
    assert!(e.message.contains(words), "{e}");
}

#[test]
fn deep_nesting_is_refused_before_the_stack_overflows() {
    // Each text is under MAX_TEXT_BYTES, so only the depth limit stops it.
    // The position is that of the 65th level's '(' or '-' (a leading '-' is not a level).
    let texts = [
        (format!("{}a*x{}", "(".repeat(4990), ")".repeat(4990)), 65),
        (format!("{}a*x", "-".repeat(9990)), 66),
        (format!("a*{}x{}", "sign(".repeat(1600), ")".repeat(1600)), 2 + 65 * 5),
        (format!("a*{}x{}", "-(".repeat(3300), ")".repeat(3300)), 2 * 65),
    ];
    for (text, position) in texts {
        assert!(text.len() <= MAX_TEXT_BYTES);
        let r = on_small_stack(move || one_state(text));
        assert_limit(r, "equation for x", &format!("nested more than 64 levels deep at position {position}:"));
    }
    // 64 levels are parsed, 65 are not.
    let at = |n: usize| format!("{}a*x{}", "(".repeat(n), ")".repeat(n));
    let (s, _) = on_small_stack(move || one_state(at(MAX_DEPTH))).unwrap();
    assert_eq!(s.params(), 1);
    let r = on_small_stack(move || one_state(at(MAX_DEPTH + 1)));
    assert_limit(r, "equation for x", "nested more than 64 levels");
}

#[test]
fn long_texts_are_refused_before_they_are_read() {
    // The texts of the report: they crashed the parser (stack overflow) or, with 200,000
    // parameter names, took minutes in name comparisons.
    let texts = [
        format!("{}a*x{}", "(".repeat(10_000), ")".repeat(10_000)),
        format!("{}a*x", "-".repeat(20_000)),
        format!("a*{}x{}", "sign(".repeat(10_000), ")".repeat(10_000)),
        (0..200_000).map(|i| format!("p{i}*x")).collect::<Vec<_>>().join(" + "),
    ];
    for text in texts {
        let n = text.len();
        let t = std::time::Instant::now();
        let r = on_small_stack(move || one_state(text));
        assert_limit(r, "equation for x", &format!("{n} bytes long; at most 10000 are supported"));
        assert!(t.elapsed().as_secs_f64() < 1.0, "{:?}", t.elapsed());
    }
    let r = one_state(format!("a*x{}", " ".repeat(MAX_TEXT_BYTES - 3)));
    assert_eq!(r.unwrap().0.params(), 1);
}

#[test]
fn products_are_sized_before_they_are_expanded() {
    // 2^40 terms before like terms are merged: one term once they are.
    let text = format!("{}*a*x", ["(1+1)"; 40].join("*"));
    let (s, _) = one_state(text).unwrap();
    let mut h = [0.0];
    s.regression(0, &[1.0], &[0.0], &[], &mut h);
    assert_eq!(h[0], 2f64.powi(40));
    // 12 parameters times 9 states: 108 different terms.
    let states = ["x", "y1", "y2", "y3", "y4", "y5", "y6", "y7", "y8"];
    let text = "(a+b+c+d+e+f+g+h+i+j+k+l)*(x+y1+y2+y3+y4+y5+y6+y7+y8)";
    let r = StructureBuilder::new(&states, &[]).equation("x", text).build::<f64>();
    assert_limit(r, "equation for x", "the product ending at position 53 has 12 × 9 terms: at most 96");
}

#[test]
fn sums_are_bounded_once_like_terms_are_merged() {
    let states: Vec<String> = (0..16).map(|i| format!("x{i}")).collect();
    let inputs: Vec<String> = (0..8).map(|i| format!("u{i}")).collect();
    let build = |text: &str| StructureBuilder::new(&states, &inputs).equation("x0", text).build::<f64>();
    // 200 copies of one term are one term.
    let (s, _) = build(&["a*x1"; 200].join(" + ")).unwrap();
    let mut h = [0.0];
    let mut x = [0.0; 16];
    x[1] = 1.0;
    s.regression(0, &x, &[0.0; 16], &[0.0; 8], &mut h);
    assert_eq!(h[0], 200.0);
    // 5 parameters times 24 variables: 120 different terms.
    let vars: Vec<&String> = states.iter().chain(&inputs).collect();
    let text = ["a", "b", "c", "d", "e"]
        .iter()
        .flat_map(|p| vars.iter().map(move |v| format!("{p}*{v}")))
        .collect::<Vec<_>>()
        .join(" + ");
    assert_limit(build(&text), "equation for x0", "more than 96 different terms in the sum by position");
}

#[test]
fn counts_are_checked_before_names_are_compared() {
    let many = |prefix: &str, n: usize| (0..n).map(|i| format!("{prefix}{i}")).collect::<Vec<_>>();
    let t = std::time::Instant::now();
    let r = StructureBuilder::new(&["x"], &[]).parameters(&many("p", 200_000)).equation("x", "p0*x").build();
    assert_limit(r, "parameters", "200000 given; at most 32 are supported");
    let r = StructureBuilder::new(&many("x", 200_000), &[]).equation("x0", "a*x0").build();
    assert_limit(r, "states", "200000 given; at most 16 are supported");
    let r = StructureBuilder::new(&many("x", 2), &many("u", 200_000)).equation("x0", "a*x0").build();
    assert_limit(r, "inputs", "200000 given; at most 8 are supported");
    assert!(t.elapsed().as_secs_f64() < 1.0, "{:?}", t.elapsed());
    let mut b = StructureBuilder::new(&["x"], &[]);
    for _ in 0..17 {
        b = b.equation("x", "a*x");
    }
    assert_limit(b.build(), "equations", "17 given; at most 16 are supported");
    // Parameters found in the text: the parse stops at the 33rd, in whichever equation.
    let text = (0..33).map(|i| format!("p{i}*x")).collect::<Vec<_>>().join(" + ");
    assert_limit(one_state(text), "equation for x", "'p32' (ending at position 249) would be parameter 33");
    let r = StructureBuilder::new(&["x", "y"], &[])
        .equation("x", &(0..20).map(|i| format!("p{i}*x")).collect::<Vec<_>>().join(" + "))
        .equation("y", &(10..40).map(|i| format!("p{i}*y")).collect::<Vec<_>>().join(" + "))
        .build::<f64>();
    assert_limit(r, "equation for y", "'p32'");
    // The names are still checked, once each.
    let r = StructureBuilder::new(&["x", "v", "x"], &[]).equation("x", "a*x").build::<f64>();
    assert_limit(r, "states", "'x' is given twice");
    let r = StructureBuilder::new(&["x"], &["u", "x"]).equation("x", "a*x").build::<f64>();
    assert_limit(r, "inputs", "'x' is also a state");
    let r = StructureBuilder::new(&["x"], &["u"]).parameters(&["a", "u"]).equation("x", "a*x").build::<f64>();
    assert_limit(r, "parameters", "'u' is also a state or input name");
}

/// Two parameters on the same function of a combination, however the combination is written,
/// are confounded and refused (had each function term a combination of its own, even
/// `a*sign(v) + b*sign(v)` would be taken, and a prior would make up a split of the two).
#[test]
fn parameters_on_one_function_written_two_ways_are_confounded() {
    for text in [
        "a*sign(v) + b*sign(v)",
        "a*sign(v) + b*sign(3*v)",
        "a*sign(v - w) - b*sign(2*w - 2*v)",
        "a*sign(v + w) + b*sign(w + v)",
        "a*pos(v - w) + b*neg(w - v)",
        "a*neg(2*v) + b*neg(v)",
        "a*pos(-v) + b*neg(v)",
    ] {
        let e = build(&[("v", text)]).unwrap_err();
        assert!(e.message.contains("'a' and 'b' multiply the same terms"), "{text}: {e}");
    }
    // Different functions of one combination, or one function of different ones, are not.
    for text in ["a*pos(v) + b*neg(v)", "a*sign(v) + b*sign(v - w)", "a*pos(v - w) + b*pos(w - v)"] {
        assert!(build(&[("v", text)]).is_ok(), "{text}");
    }
}

/// The canonical form (`canonical`) evaluates as the text: `sign(c e) = sign(c) sign(e)`,
/// `pos(c e)` / `neg(c e)` with the scale outside and, for `c < 0`, the function swapped.
#[test]
fn a_function_of_a_scaled_or_reordered_combination_evaluates_as_written() {
    type Truth = fn(f64, f64, f64) -> f64;
    let cases: [(&str, Truth); 6] = [
        ("a*sign(-3*v + w)", |_, v, w| (-3.0 * v + w).signum() * f64::from(-3.0 * v + w != 0.0)),
        ("a*pos(-2*v + w)", |_, v, w| (-2.0 * v + w).max(0.0)),
        ("a*neg(-2*v + w)", |_, v, w| (-2.0 * v + w).min(0.0)),
        ("a*pos(w - 0.5*v)", |_, v, w| (w - 0.5 * v).max(0.0)),
        ("a*neg(4*w + 2*q)", |q, _, w| (4.0 * w + 2.0 * q).min(0.0)),
        ("a*sign(w - v - q)", |q, v, w| (w - v - q).signum() * f64::from(w - v - q != 0.0)),
    ];
    let mut seed = 7u64;
    let mut next = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64) * 4.0 - 2.0
    };
    for (text, f) in cases {
        let (s, _) = build(&[("v", text)]).unwrap();
        for _ in 0..200 {
            let x = [next(), next(), next()];
            let mut h = [0.0; 1];
            s.regression(0, &x, &[0.0; 3], &[0.0], &mut h);
            let want = f(x[0], x[1], x[2]);
            assert!((h[0] - want).abs() <= 1e-12 * (1.0 + want.abs()), "{text} at {x:?}: {} for {want}", h[0]);
        }
    }
}

/// Terms that are linearly dependent as functions (not proportional pairs): refused, naming
/// the parameters involved; independent ones that look alike are taken.
#[test]
fn linearly_dependent_terms_are_refused_naming_their_parameters() {
    for (text, named) in [
        ("a*v + b*pos(v) + c*neg(v)", &["'a'", "'b'", "'c'"][..]),
        ("a*(v - w) + b*v + c*w", &["'a'", "'b'", "'c'"][..]),
        ("d*q + a*pos(v - w) + b*neg(v - w) + c*(w - v)", &["'a'", "'b'", "'c'"][..]),
    ] {
        let e = build(&[("v", text)]).unwrap_err();
        assert!(e.message.contains("not separately identifiable"), "{text}: {e}");
        for n in named {
            assert!(e.message.contains(n), "{text}: {e} should name {n}");
        }
        assert!(!e.message.contains("'d'"), "{text}: {e}");
    }
    for text in ["a*v + b*pos(v)", "a*pos(v) + b*neg(v)", "a*sign(v) + b*v + c*pos(v - w)", "a*v + b*w + c*q"] {
        assert!(build(&[("v", text)]).is_ok(), "{text}");
    }
    // Across equations: the same parameter pair in two equations, dependent only jointly, is fine.
    assert!(build(&[("v", "a*v + b*w"), ("w", "a*w + b*v")]).is_ok());
}
