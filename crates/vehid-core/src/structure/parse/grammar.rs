//! The grammar of an equation's text: a recursive-descent parser from the lexer's tokens to a
//! polynomial in the parameters and bases, expanded and its like terms merged.

use super::*;

impl Ctx<'_> {
    pub(super) fn parse(&mut self, text: &str, item: &str, params_allowed: bool) -> Result<Poly, StructureError> {
        if text.len() > MAX_TEXT_BYTES {
            return err(
                item,
                format!(
                    "the text is {} bytes long; at most {MAX_TEXT_BYTES} are supported (and {MAX_TERMS} terms): \
                     shorten the names or simplify the expression",
                    text.len()
                ),
            );
        }
        let mut lx = Lexer { text, pos: 0 };
        let at = |lx: &Lexer<'_>, msg: String| StructureError {
            item: item.to_string(),
            message: format!("{msg} at position {} of \"{text}\"", lx.pos + 1),
        };
        let poly = self.expr(&mut lx, item, params_allowed, 0).map_err(|stop| match stop {
            Stop::Syntax(m) => at(&lx, m),
            Stop::Limit(message) => StructureError { item: item.to_string(), message },
        })?;
        match lx.next().map_err(|m| at(&lx, m))? {
            Tok::End => {}
            t => return Err(at(&lx, format!("unexpected {}", describe(&t)))),
        }
        let poly = collect(poly);
        if poly.is_empty() {
            return err(item, format!("\"{text}\" is zero"));
        }
        Ok(poly)
    }

    /// A sum at nesting `depth`; at most MAX_TERMS terms once like terms are merged.
    fn expr(&mut self, lx: &mut Lexer<'_>, item: &str, pa: bool, depth: usize) -> Result<Poly, Stop> {
        let mut sign = 1.0;
        match lx.peek()? {
            Tok::Op('+') => {
                lx.next()?;
            }
            Tok::Op('-') => {
                lx.next()?;
                sign = -1.0;
            }
            _ => {}
        }
        let mut out = scale(self.product(lx, item, pa, depth)?, sign);
        loop {
            match lx.peek()? {
                Tok::Op('+') => {
                    lx.next()?;
                    out.extend(self.product(lx, item, pa, depth)?);
                }
                Tok::Op('-') => {
                    lx.next()?;
                    out.extend(scale(self.product(lx, item, pa, depth)?, -1.0));
                }
                _ => return Ok(out),
            }
            if out.len() > MAX_TERMS {
                out = collect(out);
                if out.len() > MAX_TERMS {
                    return Err(Stop::Limit(format!(
                        "more than {MAX_TERMS} different terms in the sum by position {}: at most {MAX_TERMS} are \
                         supported",
                        lx.pos
                    )));
                }
            }
        }
    }

    /// A product at nesting `depth`, expanded; its size (the product of its factors' sizes) is
    /// checked against MAX_TERMS before it is expanded.
    fn product(&mut self, lx: &mut Lexer<'_>, item: &str, pa: bool, depth: usize) -> Result<Poly, Stop> {
        let mut acc = self.factor(lx, item, pa, depth)?;
        loop {
            match lx.peek()? {
                Tok::Op('*') => {
                    lx.next()?;
                    let mut f = self.factor(lx, item, pa, depth)?;
                    if acc.len().saturating_mul(f.len()) > MAX_TERMS {
                        (acc, f) = (collect(acc), collect(f));
                        if acc.len().saturating_mul(f.len()) > MAX_TERMS {
                            return Err(Stop::Limit(format!(
                                "the product ending at position {} has {} × {} terms: at most {MAX_TERMS} are \
                                 supported",
                                lx.pos,
                                acc.len(),
                                f.len()
                            )));
                        }
                    }
                    acc = multiply(&acc, &f, self)?;
                }
                Tok::Op('/') => {
                    lx.next()?;
                    match lx.next()? {
                        Tok::Num(d) if d != 0.0 => acc = scale(acc, 1.0 / d),
                        Tok::Num(_) => return Err("division by zero".into()),
                        t => {
                            return Err(format!(
                                "division by {} (divide only by numbers: the model must stay linear in its parameters; \
                                 make the quotient one parameter)",
                                describe(&t)
                            )
                            .into())
                        }
                    }
                }
                _ => return Ok(acc),
            }
        }
    }

    /// A factor at nesting `depth`: parentheses, a function call or a unary minus descend one
    /// level, at most to MAX_DEPTH (checked before the parser recurses).
    fn factor(&mut self, lx: &mut Lexer<'_>, item: &str, pa: bool, depth: usize) -> Result<Poly, Stop> {
        match lx.next()? {
            Tok::Num(c) => Ok(vec![Mono { coef: c, param: None, basis: None }]),
            Tok::Op('(') => {
                let e = self.expr(lx, item, pa, deeper(depth, lx)?)?;
                expect_close(lx)?;
                Ok(e)
            }
            Tok::Op('-') => Ok(scale(self.factor(lx, item, pa, deeper(depth, lx)?)?, -1.0)),
            Tok::Name(n) => {
                let fun = match n.as_str() {
                    "sign" => Some(Fun::Sign),
                    "pos" => Some(Fun::Pos),
                    "neg" => Some(Fun::Neg),
                    _ => None,
                };
                if n == "der" {
                    if lx.next()? != Tok::Op('(') {
                        return Err("der must be followed by '(' and a state name".into());
                    }
                    let Tok::Name(s) = lx.next()? else { return Err("der(·) takes one state name".into()) };
                    let Some(i) = self.states.iter().position(|x| *x == s) else {
                        return Err(
                            format!("der({s}): '{s}' is not a state (states: {})", self.states.join(", ")).into()
                        );
                    };
                    expect_close(lx)?;
                    return Ok(vec![Mono { coef: 1.0, param: None, basis: Some(B::Var(Var::Deriv(i as u8))) }]);
                }
                if let Some(f) = fun {
                    if lx.next()? != Tok::Op('(') {
                        return Err(
                            format!("{n} must be followed by '(' and a combination of states and inputs").into()
                        );
                    }
                    let inner = self.expr(lx, item, pa, deeper(depth, lx)?)?;
                    expect_close(lx)?;
                    let mut comb = Vec::new();
                    for m in collect(inner) {
                        match (m.param, m.basis) {
                            (None, Some(B::Var(v))) => comb.push((v, m.coef)),
                            (Some(p), _) => {
                                return Err(format!(
                                    "{n}(·) holds the parameter '{}': inside {n}(·) only states, inputs and der(·) may \
                                     appear (is it a misspelled name? states: {}; inputs: {})",
                                    self.params[p],
                                    self.states.join(", "),
                                    list(self.inputs)
                                )
                                .into())
                            }
                            (None, None) => {
                                return Err(format!(
                                    "{n}(·) holds a constant: only states, inputs and der(·) may appear"
                                )
                                .into())
                            }
                            (None, Some(B::Fun(..))) => {
                                return Err(format!("{n}(·) of a function is not supported").into())
                            }
                        }
                    }
                    if comb.is_empty() {
                        return Err(format!("{n}(·) of zero").into());
                    }
                    let (coef, f, comb) = canonical(f, comb);
                    return Ok(vec![Mono { coef, param: None, basis: Some(B::Fun(f, comb)) }]);
                }
                if let Some(i) = self.states.iter().position(|x| *x == n) {
                    return Ok(vec![Mono { coef: 1.0, param: None, basis: Some(B::Var(Var::State(i as u8))) }]);
                }
                if let Some(j) = self.inputs.iter().position(|x| *x == n) {
                    return Ok(vec![Mono { coef: 1.0, param: None, basis: Some(B::Var(Var::Input(j as u8))) }]);
                }
                if !pa {
                    return Err(format!(
                        "'{n}' is not a state or input (known equations take no parameters; states: {}; inputs: {})",
                        self.states.join(", "),
                        list(self.inputs)
                    )
                    .into());
                }
                let p = match self.params.iter().position(|x| *x == n) {
                    Some(p) => p,
                    None if self.fixed => {
                        return Err(format!(
                        "'{n}' is not a state, input or declared parameter (states: {}; inputs: {}; parameters: {})",
                        self.states.join(", "),
                        list(self.inputs),
                        self.params.join(", ")
                    )
                        .into())
                    }
                    None if self.params.len() == MAX_PARAMS => {
                        return Err(Stop::Limit(format!(
                            "'{n}' (ending at position {}) would be parameter {}: at most {MAX_PARAMS} are supported \
                             (shared by all equations)",
                            lx.pos,
                            MAX_PARAMS + 1
                        )))
                    }
                    None => {
                        self.params.push(n);
                        self.params.len() - 1
                    }
                };
                Ok(vec![Mono { coef: 1.0, param: Some(p), basis: None }])
            }
            t => Err(format!("expected a number, a name or '(' but found {}", describe(&t)).into()),
        }
    }
}

/// `depth + 1`, or the limit error when that is beyond MAX_DEPTH.
fn deeper(depth: usize, lx: &Lexer<'_>) -> Result<usize, Stop> {
    if depth < MAX_DEPTH {
        return Ok(depth + 1);
    }
    Err(Stop::Limit(format!(
        "nested more than {MAX_DEPTH} levels deep at position {}: at most {MAX_DEPTH} levels of parentheses, \
         function calls and unary minus signs are supported; simplify the expression",
        lx.pos
    )))
}

fn list(names: &[String]) -> String {
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}

fn expect_close(lx: &mut Lexer<'_>) -> Result<(), String> {
    match lx.next()? {
        Tok::Op(')') => Ok(()),
        t => Err(format!("expected ')' but found {}", describe(&t))),
    }
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Num(v) => format!("the number {v}"),
        Tok::Name(n) => format!("'{n}'"),
        Tok::Op(c) => format!("'{c}'"),
        Tok::End => "the end".to_string(),
    }
}

fn scale(mut p: Poly, c: f64) -> Poly {
    for m in &mut p {
        m.coef *= c;
    }
    p
}

/// The expanded product of two polynomials; a term with two parameters or two bases is an
/// error (the model must be linear in its parameters, and terms are single basis functions).
fn multiply(a: &Poly, b: &Poly, ctx: &Ctx<'_>) -> Result<Poly, String> {
    let mut out = Vec::with_capacity(a.len() * b.len());
    for x in a {
        for y in b {
            let param = match (x.param, y.param) {
                (Some(p), Some(q)) => {
                    let (pn, qn) = (&ctx.params[p], &ctx.params[q]);
                    return Err(format!(
                        "'{pn}*{qn}' multiplies two parameters, which is not linear in the parameters: make the \
                         product one parameter, or is one of them a misspelled state or input? (states: {}; inputs: {})",
                        ctx.states.join(", "),
                        list(ctx.inputs)
                    ));
                }
                (p, q) => p.or(q),
            };
            let basis = match (&x.basis, &y.basis) {
                (Some(_), Some(_)) => {
                    return Err("a product of two variables: a term is a parameter times one state, input, der(·), \
                                sign(·), pos(·) or neg(·) (add the product as a measured input)"
                        .into())
                }
                (p, q) => p.clone().or_else(|| q.clone()),
            };
            out.push(Mono { coef: x.coef * y.coef, param, basis });
        }
    }
    Ok(out)
}

/// A function of a combination in one form for every way of writing it, so that equal terms
/// are seen to be equal (merged, and confounded parameters found): the entries in the order of
/// their variables (states, inputs, derivatives), scaled so that the first coefficient is 1,
/// the scale `c` moved outside: `sign(c e) = sign(c) sign(e)`, `pos(c e) = c pos(e)` and
/// `neg(c e) = c neg(e)` for `c > 0`, `pos(c e) = c neg(e)` and `neg(c e) = c pos(e)` for
/// `c < 0`. Returns the factor outside, the function and the combination.
/// (`sign(3*x)` is `sign(x)`; `neg(v - x)` is `-pos(x - v)`.)
fn canonical(f: Fun, mut comb: Vec<(Var, f64)>) -> (f64, Fun, Vec<(Var, f64)>) {
    fn key(v: Var) -> (u8, u8) {
        match v {
            Var::State(i) => (0, i),
            Var::Input(j) => (1, j),
            Var::Deriv(i) => (2, i),
        }
    }
    comb.sort_by_key(|&(v, _)| key(v));
    let c = comb[0].1;
    for e in &mut comb {
        e.1 /= c;
    }
    comb[0].1 = 1.0; // exactly, whatever the rounding of c / c
    match (f, c > 0.0) {
        (Fun::Sign, _) => (c.signum(), Fun::Sign, comb),
        (Fun::Pos, true) | (Fun::Neg, false) => (c, Fun::Pos, comb),
        (Fun::Neg, true) | (Fun::Pos, false) => (c, Fun::Neg, comb),
    }
}

/// Merges monomials with the same parameter and basis, drops zeros, keeps first-appearance order.
fn collect(p: Poly) -> Poly {
    let mut out: Poly = Vec::new();
    for m in p {
        match out.iter_mut().find(|o| o.param == m.param && o.basis == m.basis) {
            Some(o) => o.coef += m.coef,
            None => out.push(m),
        }
    }
    out.retain(|m| m.coef != 0.0);
    out
}
