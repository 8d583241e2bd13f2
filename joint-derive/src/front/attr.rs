//! The attribute AST: `#[joint(...)]`, `#[body(...)]`, `#[scene(...)]` items as
//! written, every value with its span, numbers folded where they can be.
//!
//! ```text
//! ARG    = KEY | KEY = VALUE | rows(EXPR, ..) | KEY(ARG, ..)
//! VALUE  = NAME | NUMBER | [NUMBER, ..]
//! NUMBER = a literal, arithmetic on literals (folded here, so geometry checks
//!          still see it), or arithmetic with named constants (`RA`, `consts::D`),
//!          emitted as written for the compiler to fold
//! ```

use proc_macro2::Span;
use quote::ToTokens;
use syn::parse::{Parse, ParseStream};
use syn::punctuated::Punctuated;
use syn::spanned::Spanned;
use syn::{Token, bracketed};

use super::context::Errors;

/// A number as written: known to the derive, or naming constants it cannot read.
#[derive(Clone)]
pub enum Number {
    /// A literal, or arithmetic on literals, folded as Rust would (each
    /// operation rounded once, left to right as written).
    Known(f64),
    /// Arithmetic that names a constant (`-RA`, `0.007 - consts::D`): emitted
    /// as written, an `f64` expression the compiler folds.
    Named(syn::Expr),
}

impl Number {
    /// The value, if the derive knows it.
    pub fn known(&self) -> Option<f64> {
        match self {
            Number::Known(x) => Some(*x),
            Number::Named(_) => None,
        }
    }
}

/// `number` with the identifier `var` replaced by `value` (a row of joints'
/// variable), folded when nothing else is named.
pub fn substitute(number: &Number, var: &syn::Ident, value: i64) -> syn::Result<Number> {
    let Number::Named(expr) = number else { return Ok(number.clone()) };
    fn walk(tokens: proc_macro2::TokenStream, var: &syn::Ident, value: i64) -> proc_macro2::TokenStream {
        tokens
            .into_iter()
            .map(|t| match t {
                proc_macro2::TokenTree::Ident(i) if i == *var => {
                    let mut lit = proc_macro2::Literal::i64_unsuffixed(value.abs());
                    lit.set_span(i.span());
                    let inner: proc_macro2::TokenStream =
                        if value < 0 { quote::quote!(-#lit) } else { quote::quote!(#lit) };
                    proc_macro2::TokenTree::Group(proc_macro2::Group::new(proc_macro2::Delimiter::Parenthesis, inner))
                }
                proc_macro2::TokenTree::Group(g) => {
                    let mut out = proc_macro2::Group::new(g.delimiter(), walk(g.stream(), var, value));
                    out.set_span(g.span());
                    proc_macro2::TokenTree::Group(out)
                }
                other => other,
            })
            .collect()
    }
    let replaced: syn::Expr = syn::parse2(walk(expr.to_token_stream(), var, value))?;
    self::number(&replaced)
}

/// The values of a list when every one is known.
pub fn known(values: &[Number]) -> Option<Vec<f64>> {
    values.iter().map(Number::known).collect()
}

/// A value written in `KEY = VALUE` or `KEY(...)`.
pub enum Value {
    /// A bare identifier: a name (`omega_body`, `body1`), a field of a scene, or
    /// a named constant, as the key decides.
    Ident(syn::Ident),
    /// A number.
    Number(Number, Span),
    /// `[x, y, z]`.
    List(Vec<Number>, Span),
    /// `rows(e1, e2, ...)`: user-written rows.
    Rows(Vec<syn::Expr>, Span),
    /// `body1(s = [..], ...)`: constants tagged with a body.
    Group(Vec<Arg>, Span),
    /// `"robot.urdf"`: a file's path.
    Text(syn::LitStr),
}

impl Value {
    /// Where the value was written.
    pub fn span(&self) -> Span {
        match self {
            Value::Ident(i) => i.span(),
            Value::Text(t) => t.span(),
            Value::Number(_, s) | Value::List(_, s) | Value::Rows(_, s) | Value::Group(_, s) => *s,
        }
    }

    /// The value as numbers, where numbers are expected (a bare identifier is
    /// then a named constant).
    pub fn numbers(self) -> Option<(Vec<Number>, Span)> {
        match self {
            Value::Number(x, s) => Some((vec![x], s)),
            Value::List(v, s) => Some((v, s)),
            Value::Ident(i) => {
                let span = i.span();
                Some((vec![Number::Named(syn::parse_quote_spanned!(span=> #i))], span))
            }
            Value::Rows(..) | Value::Group(..) | Value::Text(_) => None,
        }
    }
}

/// One item of an attribute.
pub struct Arg {
    /// The key (or the bare word).
    pub key: syn::Ident,
    /// The value after `=` or in parentheses, if any.
    pub value: Option<Value>,
}

const EXPECTED_NUMBER: &str = "expected a number, arithmetic on numbers or a named constant, as in `0.5`, \
                               `[0, 0, 1]`, `0.007 - 0.00092` or `-RA`";

/// A number: folded when it is arithmetic on literals, kept as written when it
/// names a constant.
pub fn number(expr: &syn::Expr) -> syn::Result<Number> {
    if names_constant(expr)? {
        return Ok(Number::Named(expr.clone()));
    }
    Ok(Number::Known(fold(expr)?))
}

/// Whether a number's expression names a constant; an error for anything that
/// is not arithmetic on literals and paths.
fn names_constant(expr: &syn::Expr) -> syn::Result<bool> {
    use syn::{BinOp, Expr, Lit, UnOp};
    Ok(match expr {
        Expr::Lit(syn::ExprLit { lit: Lit::Int(_) | Lit::Float(_), .. }) => false,
        Expr::Paren(e) => names_constant(&e.expr)?,
        Expr::Group(e) => names_constant(&e.expr)?,
        Expr::Unary(e) if matches!(e.op, UnOp::Neg(_)) => names_constant(&e.expr)?,
        Expr::Binary(e) if matches!(e.op, BinOp::Add(_) | BinOp::Sub(_) | BinOp::Mul(_) | BinOp::Div(_)) => {
            names_constant(&e.left)? | names_constant(&e.right)?
        }
        Expr::Binary(e) => {
            return Err(syn::Error::new(e.op.span(), "expected `+`, `-`, `*` or `/` between numbers"));
        }
        Expr::Path(p) if p.qself.is_none() => true,
        _ => return Err(syn::Error::new(expr.span(), EXPECTED_NUMBER)),
    })
}

/// The value of arithmetic on number literals (checked by [`names_constant`]).
fn fold(expr: &syn::Expr) -> syn::Result<f64> {
    use syn::{BinOp, Expr, Lit};
    Ok(match expr {
        Expr::Lit(syn::ExprLit { lit: Lit::Int(i), .. }) => i.base10_parse::<f64>()?,
        Expr::Lit(syn::ExprLit { lit: Lit::Float(f), .. }) => f.base10_parse::<f64>()?,
        Expr::Paren(e) => fold(&e.expr)?,
        Expr::Group(e) => fold(&e.expr)?,
        Expr::Unary(e) => -fold(&e.expr)?,
        Expr::Binary(e) => {
            let (a, b) = (fold(&e.left)?, fold(&e.right)?);
            match e.op {
                BinOp::Add(_) => a + b,
                BinOp::Sub(_) => a - b,
                BinOp::Mul(_) => a * b,
                _ => a / b,
            }
        }
        // A non-finite result (`1.0 / 0.0`) is the parameter checks' to report.
        _ => return Err(syn::Error::new(expr.span(), EXPECTED_NUMBER)),
    })
}

fn list(input: ParseStream) -> syn::Result<Value> {
    let content;
    let bracket = bracketed!(content in input);
    let items = Punctuated::<syn::Expr, Token![,]>::parse_terminated(&content)
        .map_err(|e| syn::Error::new(e.span(), EXPECTED_NUMBER))?;
    let values = items.iter().map(number).collect::<syn::Result<_>>()?;
    Ok(Value::List(values, bracket.span.join()))
}

impl Parse for Arg {
    fn parse(input: ParseStream) -> syn::Result<Self> {
        let key: syn::Ident = input.parse()?;
        if input.peek(syn::token::Paren) {
            let content;
            let paren = syn::parenthesized!(content in input);
            let value = if key == "rows" {
                let rows = Punctuated::<syn::Expr, Token![,]>::parse_terminated(&content)?;
                Value::Rows(rows.into_iter().collect(), paren.span.join())
            } else {
                Value::Group(args(&content)?, paren.span.join())
            };
            return Ok(Arg { key, value: Some(value) });
        }
        if input.parse::<Option<Token![=]>>()?.is_none() {
            return Ok(Arg { key, value: None });
        }
        if input.peek(syn::token::Bracket) {
            return Ok(Arg { key, value: Some(list(input)?) });
        }
        if input.peek(syn::LitStr) {
            return Ok(Arg { key, value: Some(Value::Text(input.parse()?)) });
        }
        let expr: syn::Expr = input.parse().map_err(|e| syn::Error::new(e.span(), EXPECTED_NUMBER))?;
        let value = match &expr {
            syn::Expr::Path(p) if p.qself.is_none() && p.path.get_ident().is_some() => {
                Value::Ident(p.path.get_ident().cloned().unwrap_or_else(|| key.clone()))
            }
            _ => Value::Number(number(&expr)?, expr.span()),
        };
        Ok(Arg { key, value: Some(value) })
    }
}

/// `ARG, ARG, ...` up to the end of `input`.
pub fn args(input: ParseStream) -> syn::Result<Vec<Arg>> {
    Ok(Punctuated::<Arg, Token![,]>::parse_terminated(input)?.into_iter().collect())
}

/// `ARG, ARG, ...` up to the end of `input` or a `;` (which is left).
pub fn args_until_semicolon(input: ParseStream) -> syn::Result<Vec<Arg>> {
    let mut out = Vec::new();
    while !input.is_empty() && !input.peek(Token![;]) {
        out.push(input.parse()?);
        if input.is_empty() || input.peek(Token![;]) {
            break;
        }
        input.parse::<Token![,]>()?;
    }
    Ok(out)
}

/// `ITEM; ITEM; ...`: several entries in one attribute (a scene of many
/// joints: rustc counts each attribute of an item against its recursion limit,
/// and stops near 128).
pub fn entries<T: Parse>(attr: &syn::Attribute) -> syn::Result<Vec<T>> {
    Ok(attr.parse_args_with(Punctuated::<T, Token![;]>::parse_terminated)?.into_iter().collect())
}

/// The items of every attribute called `name` on an item or field; parse
/// errors are recorded.
pub fn items(attrs: &[syn::Attribute], name: &str, errors: &mut Errors) -> Vec<Arg> {
    let mut out = Vec::new();
    for attr in attrs.iter().filter(|a| a.path().is_ident(name)) {
        match attr.parse_args_with(args) {
            Ok(parsed) => out.extend(parsed),
            Err(e) => errors.push(e),
        }
    }
    out
}

/// The named fields of the struct (`None` for a unit struct).
pub type Fields = Option<Punctuated<syn::Field, syn::Token![,]>>;

/// An attribute slot that takes one value and reports a second one itself
/// (after serde's `Attr`).
pub struct Slot<T> {
    what: &'static str,
    expected: &'static str,
    value: Option<(T, Span)>,
    /// A value was written, accepted or not (a misspelt one is not also missing).
    pub written: bool,
}

impl<T> Slot<T> {
    /// An empty slot; `what` and `expected` word the duplicate error:
    /// "{what} is given twice; expected {expected}".
    pub fn new(what: &'static str, expected: &'static str) -> Self {
        Slot { what, expected, value: None, written: false }
    }

    /// Fills the slot, or reports that it was already filled.
    pub fn set(&mut self, span: Span, value: T, errors: &mut Errors) {
        self.written = true;
        if self.value.is_some() {
            errors.at(span, format!("{} is given twice; expected {}", self.what, self.expected));
        } else {
            self.value = Some((value, span));
        }
    }

    /// The value and where it was written, taken out of the slot.
    pub fn take(&mut self) -> Option<(T, Span)> {
        self.value.take()
    }
}

/// Whether `tokens` contain one of the identifiers `names`.
pub fn mentions(tokens: &impl ToTokens, names: &[String]) -> bool {
    fn walk(tokens: proc_macro2::TokenStream, names: &[String]) -> bool {
        tokens.into_iter().any(|t| match t {
            proc_macro2::TokenTree::Ident(i) => names.iter().any(|n| i == n),
            proc_macro2::TokenTree::Group(g) => walk(g.stream(), names),
            _ => false,
        })
    }
    walk(tokens.to_token_stream(), names)
}
