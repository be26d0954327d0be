//! The equation parser (`structure/parse.rs`) against an independent evaluator: random
//! expressions over states, an input, parameters and numbers with `+`, `-`, `*`, `/ number`,
//! parentheses and unary minus (at the start of an expression and before any factor); the
//! text is evaluated by a tiny evaluator written here, at random values, and compared with
//! the parsed structure's `Σ θ·term` (`Structure::derivative`).
//!
//! The generator keeps every product linear in the parameters (no two factors that both hold
//! a parameter, or both a variable), as the grammar requires; expressions the builder refuses
//! for what they mean (zero, no parameter, a parameter that cancels, two confounded
//! parameters) are counted and skipped, and must be a small share.

use vehid_core::structure::StructureBuilder;

const STATES: [&str; 3] = ["q", "v", "w"];
const INPUTS: [&str; 1] = ["u"];
const PARAMS: [&str; 4] = ["a", "b", "c", "k"];

/// splitmix64: a small deterministic generator.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next() >> 11) as f64 / (1u64 << 53) as f64)
    }
}

/// A random expression whose terms may hold a parameter only if `param` and a variable only if
/// `var`, `depth` levels at most; returns its text.
fn expr(rng: &mut Rng, depth: usize, param: bool, var: bool) -> String {
    let n = 1 + rng.below(if depth == 0 { 1 } else { 3 });
    let mut s = String::new();
    for i in 0..n {
        let sign = match (i, rng.below(4)) {
            (0, 0) => "-",
            (0, 1) => "+",
            (0, _) => "",
            (_, 0 | 1) => " - ",
            _ => " + ",
        };
        s.push_str(sign);
        s.push_str(&product(rng, depth, param, var));
    }
    s
}

/// A product of factors that share out the parameter and the variable (at most one factor
/// may hold each), sometimes divided by a number.
fn product(rng: &mut Rng, depth: usize, param: bool, var: bool) -> String {
    let n = 1 + rng.below(3);
    let p_at = if param { rng.below(n + 1) } else { n };
    let v_at = if var { rng.below(n + 1) } else { n };
    let mut s = String::new();
    for i in 0..n {
        if i > 0 {
            s.push('*');
        }
        s.push_str(&factor(rng, depth, i == p_at, i == v_at));
    }
    if rng.below(6) == 0 {
        s.push_str(&format!("/{}", ["2", "4", "0.5", "8"][rng.below(4)]));
    }
    s
}

fn number(rng: &mut Rng) -> String {
    ["2", "3", "0.5", "1.25", "7", "10", "0.1", "4.5e-1"][rng.below(8)].to_string()
}

fn factor(rng: &mut Rng, depth: usize, param: bool, var: bool) -> String {
    let choice = rng.below(if depth == 0 { 3 } else { 6 });
    match choice {
        // A leaf: what this factor may hold.
        0..=2 => {
            let mut names: Vec<&str> = Vec::new();
            if param {
                names.extend(PARAMS);
            }
            if var {
                names.extend(STATES);
                names.extend(INPUTS);
            }
            if names.is_empty() || rng.below(5) == 0 {
                number(rng)
            } else {
                names[rng.below(names.len())].to_string()
            }
        }
        3 | 4 => format!("({})", expr(rng, depth - 1, param, var)),
        _ => format!("-{}", factor(rng, depth - 1, param, var)),
    }
}

/// The independent evaluator: `expr := [+|-] term ((+|-) term)*`, `term := factor ((*|/)
/// factor)*`, `factor := number | name | ( expr ) | - factor`, over bytes, with the values of
/// the names. Returns the value and a magnitude (the same sum with every term's absolute
/// value) for the comparison's rounding allowance.
struct Eval<'a> {
    s: &'a [u8],
    i: usize,
    value: &'a dyn Fn(&str) -> f64,
}

impl Eval<'_> {
    fn peek(&mut self) -> Option<u8> {
        while self.i < self.s.len() && self.s[self.i] == b' ' {
            self.i += 1;
        }
        self.s.get(self.i).copied()
    }
    fn expr(&mut self) -> (f64, f64) {
        let mut sign = 1.0;
        if let Some(c @ (b'+' | b'-')) = self.peek() {
            self.i += 1;
            if c == b'-' {
                sign = -1.0;
            }
        }
        let (t, m) = self.term();
        let (mut v, mut mag) = (sign * t, m);
        while let Some(c @ (b'+' | b'-')) = self.peek() {
            self.i += 1;
            let (t, m) = self.term();
            v += if c == b'+' { t } else { -t };
            mag += m;
        }
        (v, mag)
    }
    fn term(&mut self) -> (f64, f64) {
        let (mut v, mut mag) = self.factor();
        while let Some(c @ (b'*' | b'/')) = self.peek() {
            self.i += 1;
            let (f, m) = self.factor();
            if c == b'*' {
                (v, mag) = (v * f, mag * m);
            } else {
                (v, mag) = (v / f, mag / m);
            }
        }
        (v, mag)
    }
    fn factor(&mut self) -> (f64, f64) {
        match self.peek() {
            Some(b'-') => {
                self.i += 1;
                let (v, m) = self.factor();
                (-v, m)
            }
            Some(b'(') => {
                self.i += 1;
                let r = self.expr();
                assert_eq!(self.peek(), Some(b')'));
                self.i += 1;
                r
            }
            Some(c) if c.is_ascii_digit() || c == b'.' => {
                let start = self.i;
                while self.i < self.s.len() && (self.s[self.i].is_ascii_alphanumeric() || self.s[self.i] == b'.') {
                    // digits, '.', and an exponent written as e-1 (the '-' handled below)
                    if self.s[self.i] == b'e' && self.s.get(self.i + 1) == Some(&b'-') {
                        self.i += 1;
                    }
                    self.i += 1;
                }
                let v: f64 = std::str::from_utf8(&self.s[start..self.i]).unwrap().parse().unwrap();
                (v, v.abs())
            }
            Some(c) if c.is_ascii_alphabetic() => {
                let start = self.i;
                while self.i < self.s.len() && self.s[self.i].is_ascii_alphanumeric() {
                    self.i += 1;
                }
                let v = (self.value)(std::str::from_utf8(&self.s[start..self.i]).unwrap());
                (v, v.abs())
            }
            c => panic!("evaluator: unexpected {c:?} at {} of {:?}", self.i, std::str::from_utf8(self.s)),
        }
    }
}

fn evaluate(text: &str, value: &dyn Fn(&str) -> f64) -> (f64, f64) {
    let mut e = Eval { s: text.as_bytes(), i: 0, value };
    let r = e.expr();
    assert_eq!(e.peek(), None, "evaluator: trailing text in {text:?}");
    r
}

#[test]
fn random_expressions_evaluate_as_written() {
    let mut rng = Rng(0x5eed_0001);
    let (cases, mut built, mut refused) = (3000, 0, Vec::new());
    let mut factor_minus = 0;
    for case in 0..cases {
        // (Regenerated until a parameter appears: an equation needs one.)
        let text = loop {
            let t = expr(&mut rng, 3, true, true);
            if PARAMS.iter().any(|p| t.contains(p)) {
                break t;
            }
        };
        let parsed = StructureBuilder::new(&STATES, &INPUTS).equation("v", &text).build::<f64>();
        let (s, names) = match parsed {
            Ok(r) => r,
            Err(e) => {
                // Only refusals for what the expression means, never for its syntax.
                let m = &e.message;
                assert!(
                    m.contains("is zero")
                        || m.contains("no parameter")
                        || m.contains("appears in no identified equation")
                        || m.contains("only a combination of them")
                        || m.contains("not separately identifiable"),
                    "case {case}: {text:?} refused: {e}"
                );
                refused.push(format!("{text}: {m}"));
                continue;
            }
        };
        built += 1;
        factor_minus += usize::from(text.contains("*-") || text.contains("(-") || text.contains("--"));
        for _ in 0..3 {
            let x: Vec<f64> = (0..3).map(|_| rng.uniform(-2.0, 2.0)).collect();
            let u = [rng.uniform(-2.0, 2.0)];
            let p: Vec<f64> = (0..names.params.len()).map(|_| rng.uniform(-2.0, 2.0)).collect();
            let value = |n: &str| {
                if let Some(i) = STATES.iter().position(|s| *s == n) {
                    x[i]
                } else if n == "u" {
                    u[0]
                } else {
                    p[names.params.iter().position(|q| q == n).unwrap_or_else(|| panic!("{n} is no parameter"))]
                }
            };
            let (want, mag) = evaluate(&text, &value);
            let mut out = [0.0; 3];
            s.derivative(&p, &x, &u, &mut out);
            assert!(
                (out[1] - want).abs() <= 1e-12 * (1.0 + mag),
                "case {case}: {text:?} at x {x:?}, u {u:?}, {:?} = {p:?}: the structure gives {}, the text {want}",
                names.params,
                out[1]
            );
        }
    }
    // Enough of them built (measured: 79 %; most refusals are two parameters on the same
    // terms), and enough with a unary minus inside a product or parentheses.
    assert!(built >= cases * 2 / 3, "{built} of {cases} built; refused e.g. {:?}", &refused[..refused.len().min(5)]);
    assert!(factor_minus >= cases / 10, "{factor_minus} with a unary minus before a factor");
}
