//! PBRT syntax: turns tokens into directives with their arguments and
//! parameter lists, each with the location where it starts. No semantics here
//! (that is [`super::builder`]), except what the grammar itself needs: how many
//! arguments each directive takes and what a parameter list looks like.

use crate::error::{FileLoc, SceneError};

use super::tokenizer::{Token, TokenKind, Tokenizer};

/// The values of one parameter, as written. Numbers are kept as `f64` so that
/// integers (mesh indices) stay exact; `params` checks them against the type.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValues {
    /// `[ ]`: no values at all.
    Empty,
    /// Numbers (integers included).
    Numbers(Vec<f64>),
    /// Quoted strings.
    Strings(Vec<String>),
    /// Bare `true`/`false`.
    Bools(Vec<bool>),
}

/// One `"type name" value(s)` entry of a parameter list.
#[derive(Clone, Debug, PartialEq)]
pub struct RawParam {
    /// The declared type (`float`, `rgb`, `point3`, ...), as written.
    pub ty: String,
    /// The parameter name, as written.
    pub name: String,
    /// The values, as written.
    pub values: ParamValues,
    /// Where the declaration string starts.
    pub loc: FileLoc,
}

/// Directives that take a type name and a parameter list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EntityKind {
    Shape,
    Material,
    MakeNamedMaterial,
    LightSource,
    AreaLightSource,
    Camera,
    Film,
    Sampler,
    Integrator,
    PixelFilter,
    Accelerator,
    MakeNamedMedium,
    Attribute,
}

impl EntityKind {
    /// The directive as written in a file.
    pub fn keyword(self) -> &'static str {
        match self {
            EntityKind::Shape => "Shape",
            EntityKind::Material => "Material",
            EntityKind::MakeNamedMaterial => "MakeNamedMaterial",
            EntityKind::LightSource => "LightSource",
            EntityKind::AreaLightSource => "AreaLightSource",
            EntityKind::Camera => "Camera",
            EntityKind::Film => "Film",
            EntityKind::Sampler => "Sampler",
            EntityKind::Integrator => "Integrator",
            EntityKind::PixelFilter => "PixelFilter",
            EntityKind::Accelerator => "Accelerator",
            EntityKind::MakeNamedMedium => "MakeNamedMedium",
            EntityKind::Attribute => "Attribute",
        }
    }
}

/// One directive with its arguments.
#[derive(Clone, Debug, PartialEq)]
pub enum Statement {
    AttributeBegin,
    AttributeEnd,
    TransformBegin,
    TransformEnd,
    ObjectEnd,
    WorldBegin,
    /// pbrt-v3 only; pbrt-v4 rejects it.
    WorldEnd,
    Identity,
    ReverseOrientation,
    /// `ActiveTransform All|StartTime|EndTime`.
    ActiveTransform(String),
    Translate([f64; 3]),
    Scale([f64; 3]),
    Rotate([f64; 4]),
    LookAt([f64; 9]),
    /// The 16 numbers as written (pbrt reads them as the transpose of the matrix).
    Transform([f64; 16]),
    ConcatTransform([f64; 16]),
    TransformTimes([f64; 2]),
    CoordinateSystem(String),
    CoordSysTransform(String),
    NamedMaterial(String),
    ObjectBegin(String),
    ObjectInstance(String),
    Include(String),
    Import(String),
    ColorSpace(String),
    MediumInterface(String, String),
    /// `Option "type name" value`.
    Option(String, String),
    /// `Texture "name" "float|spectrum" "class" params`.
    Texture {
        name: String,
        ty: String,
        class: String,
        params: Vec<RawParam>,
    },
    /// `Shape "trianglemesh" params`, `Material "diffuse" params`, ...
    Entity {
        kind: EntityKind,
        name: String,
        params: Vec<RawParam>,
    },
}

/// A statement and where its keyword is.
#[derive(Clone, Debug, PartialEq)]
pub struct Directive {
    /// What the directive says.
    pub statement: Statement,
    /// Where its keyword is.
    pub loc: FileLoc,
}

/// Reads directives from one file.
pub struct Parser {
    tok: Tokenizer,
    peeked: Option<Token>,
}

/// Parses a number the way pbrt does: decimal, optional sign, fraction and
/// exponent (`1e-3`, `-.5`, `+2`). Rejects what Rust would also accept but pbrt
/// does not (`inf`, `nan`).
pub fn parse_number(s: &str) -> Option<f64> {
    let digits = s.trim_start_matches(['+', '-']);
    if s.len() - digits.len() > 1 || !digits.starts_with(|c: char| c.is_ascii_digit() || c == '.') {
        return None;
    }
    if !digits.bytes().all(|b| b.is_ascii_digit() || matches!(b, b'.' | b'e' | b'E' | b'+' | b'-')) {
        return None;
    }
    s.parse::<f64>().ok()
}

impl Parser {
    /// A parser reading from `tok`.
    pub fn new(tok: Tokenizer) -> Self {
        Parser { tok, peeked: None }
    }

    /// The name of the file being parsed.
    pub fn file(&self) -> &str {
        self.tok.file()
    }

    fn next(&mut self) -> Result<Option<Token>, SceneError> {
        match self.peeked.take() {
            Some(t) => Ok(Some(t)),
            None => self.tok.next_token(),
        }
    }

    fn peek(&mut self) -> Result<Option<Token>, SceneError> {
        if self.peeked.is_none() {
            self.peeked = self.tok.next_token()?;
        }
        Ok(self.peeked)
    }

    /// The next token, or an "unexpected end of file" error saying what was expected.
    fn required(&mut self, what: &str) -> Result<Token, SceneError> {
        match self.next()? {
            Some(t) => Ok(t),
            None => {
                Err(SceneError::at(&self.tok.end_loc(), format!("unexpected end of file: expected {what}")))
            }
        }
    }

    fn string_arg(&mut self, directive: &str) -> Result<String, SceneError> {
        let t = self.required(&format!("a quoted string after {directive}"))?;
        match t.kind {
            TokenKind::Str { .. } => Ok(self.tok.string(&t).into_owned()),
            _ => Err(SceneError::at(
                &self.tok.loc(&t),
                format!("expected a quoted string after {directive}, found '{}'", self.tok.text(&t)),
            )),
        }
    }

    fn number(&mut self, t: &Token) -> Result<f64, SceneError> {
        let text = self.tok.text(t);
        match t.kind {
            TokenKind::Word => match parse_number(text) {
                // Scene values end up as f32: beyond its range they would
                // be infinite (a camera, a light, a BVH of infinities).
                Some(v) if v.abs() > f32::MAX as f64 => Err(SceneError::at(
                    &self.tok.loc(t),
                    format!("number '{text}' is out of range (at most {:e} in size)", f32::MAX),
                )),
                Some(v) => Ok(v),
                None => Err(SceneError::at(&self.tok.loc(t), format!("bad number '{text}'"))),
            },
            TokenKind::Str { .. } => {
                Err(SceneError::at(&self.tok.loc(t), format!("expected a number, found string \"{text}\"")))
            }
            _ => Err(SceneError::at(&self.tok.loc(t), format!("expected a number, found '{text}'"))),
        }
    }

    fn numbers<const N: usize>(&mut self, directive: &str) -> Result<[f64; N], SceneError> {
        let mut v = [0.0; N];
        for x in &mut v {
            let t = self.required(&format!("{N} numbers after {directive}"))?;
            *x = self.number(&t)?;
        }
        Ok(v)
    }

    /// 16 numbers in brackets (pbrt-v4 requires them; we also accept none).
    fn matrix(&mut self, directive: &str) -> Result<[f64; 16], SceneError> {
        let bracketed = matches!(self.peek()?, Some(Token { kind: TokenKind::Open, .. }));
        if bracketed {
            self.next()?;
        }
        let m = self.numbers::<16>(directive)?;
        if bracketed {
            let t = self.required(&format!("']' closing the matrix of {directive}"))?;
            if t.kind != TokenKind::Close {
                return Err(SceneError::at(
                    &self.tok.loc(&t),
                    format!(
                        "{directive} takes exactly 16 numbers; expected ']', found '{}'",
                        self.tok.text(&t)
                    ),
                ));
            }
        }
        Ok(m)
    }

    /// Parameters follow while the next token is a quoted declaration.
    fn params(&mut self) -> Result<Vec<RawParam>, SceneError> {
        let mut params = Vec::new();
        while let Some(t @ Token { kind: TokenKind::Str { .. }, .. }) = self.peek()? {
            self.next()?;
            let loc = self.tok.loc(&t);
            let decl = self.tok.string(&t).into_owned();
            let mut words = decl.split_whitespace();
            let (Some(ty), Some(name)) = (words.next(), words.next()) else {
                return Err(SceneError::at(
                    &loc,
                    format!("parameter \"{decl}\" needs a type and a name (e.g. \"float fov\")"),
                ));
            };
            let (ty, name) = (ty.to_string(), name.to_string());
            let first = self.required(&format!("a value for parameter \"{decl}\""))?;
            let mut values = ParamValues::Empty;
            if first.kind == TokenKind::Open {
                loop {
                    let Some(v) = self.next()? else {
                        let open = self.tok.loc(&first);
                        return Err(SceneError::at(
                            &self.tok.end_loc(),
                            format!("unexpected end of file: missing ']' for parameter \"{decl}\" opened at {open}"),
                        ));
                    };
                    if v.kind == TokenKind::Close {
                        break;
                    }
                    self.push_value(&mut values, &v, &decl)?;
                }
            } else {
                self.push_value(&mut values, &first, &decl)?;
            }
            params.push(RawParam { ty, name, values, loc });
        }
        Ok(params)
    }

    fn push_value(&mut self, values: &mut ParamValues, t: &Token, decl: &str) -> Result<(), SceneError> {
        let loc = self.tok.loc(t);
        let mixed = |found: &str| {
            SceneError::at(&loc, format!("parameter \"{decl}\": {found} mixed with other values"))
        };
        match t.kind {
            TokenKind::Str { .. } => {
                let s = self.tok.string(t).into_owned();
                match values {
                    ParamValues::Empty => *values = ParamValues::Strings(vec![s]),
                    ParamValues::Strings(v) => v.push(s),
                    _ => return Err(mixed("a string")),
                }
            }
            TokenKind::Word if matches!(self.tok.text(t), "true" | "false") => {
                let b = self.tok.text(t) == "true";
                match values {
                    ParamValues::Empty => *values = ParamValues::Bools(vec![b]),
                    ParamValues::Bools(v) => v.push(b),
                    _ => return Err(mixed("a Boolean")),
                }
            }
            TokenKind::Word => {
                let x = self.number(t)?;
                match values {
                    ParamValues::Empty => *values = ParamValues::Numbers(vec![x]),
                    ParamValues::Numbers(v) => v.push(x),
                    _ => return Err(mixed("a number")),
                }
            }
            TokenKind::Open => {
                return Err(SceneError::at(
                    &loc,
                    format!("parameter \"{decl}\": unexpected '[' inside a list"),
                ))
            }
            TokenKind::Close => {
                return Err(SceneError::at(&loc, format!("parameter \"{decl}\": unexpected ']' without '['")))
            }
        }
        Ok(())
    }

    fn entity(&mut self, kind: EntityKind) -> Result<Statement, SceneError> {
        let name = self.string_arg(kind.keyword())?;
        let params = self.params()?;
        Ok(Statement::Entity { kind, name, params })
    }

    /// The next directive, `None` at the end of the file.
    pub fn next_directive(&mut self) -> Result<Option<Directive>, SceneError> {
        let Some(t) = self.next()? else { return Ok(None) };
        let loc = self.tok.loc(&t);
        let word = self.tok.text(&t).to_string();
        if t.kind != TokenKind::Word {
            let what = match t.kind {
                TokenKind::Str { .. } => format!("string \"{word}\""),
                _ => format!("'{word}'"),
            };
            return Err(SceneError::at(&loc, format!("expected a directive, found {what}")));
        }
        use EntityKind as E;
        use Statement as S;
        let statement = match word.as_str() {
            "AttributeBegin" => S::AttributeBegin,
            "AttributeEnd" => S::AttributeEnd,
            "TransformBegin" => S::TransformBegin,
            "TransformEnd" => S::TransformEnd,
            "ObjectEnd" => S::ObjectEnd,
            "WorldBegin" => S::WorldBegin,
            "WorldEnd" => S::WorldEnd,
            "Identity" => S::Identity,
            "ReverseOrientation" => S::ReverseOrientation,
            "ActiveTransform" => {
                let a = self.required("All, StartTime or EndTime after ActiveTransform")?;
                S::ActiveTransform(self.tok.text(&a).to_string())
            }
            "Translate" => S::Translate(self.numbers(&word)?),
            "Scale" => S::Scale(self.numbers(&word)?),
            "Rotate" => S::Rotate(self.numbers(&word)?),
            "LookAt" => S::LookAt(self.numbers(&word)?),
            "TransformTimes" => S::TransformTimes(self.numbers(&word)?),
            "Transform" => S::Transform(self.matrix(&word)?),
            "ConcatTransform" => S::ConcatTransform(self.matrix(&word)?),
            "CoordinateSystem" => S::CoordinateSystem(self.string_arg(&word)?),
            "CoordSysTransform" => S::CoordSysTransform(self.string_arg(&word)?),
            "NamedMaterial" => S::NamedMaterial(self.string_arg(&word)?),
            "ObjectBegin" => S::ObjectBegin(self.string_arg(&word)?),
            "ObjectInstance" => S::ObjectInstance(self.string_arg(&word)?),
            "Include" => S::Include(self.string_arg(&word)?),
            "Import" => S::Import(self.string_arg(&word)?),
            "ColorSpace" => S::ColorSpace(self.string_arg(&word)?),
            "MediumInterface" => {
                let inside = self.string_arg(&word)?;
                let outside = match self.peek()? {
                    Some(t @ Token { kind: TokenKind::Str { .. }, .. }) => {
                        self.next()?;
                        self.tok.string(&t).into_owned()
                    }
                    _ => inside.clone(),
                };
                S::MediumInterface(inside, outside)
            }
            "Option" => {
                let name = self.string_arg(&word)?;
                let v = self.required("a value after Option")?;
                S::Option(name, self.tok.string(&v).into_owned())
            }
            "Texture" => {
                let name = self.string_arg(&word)?;
                let ty = self.string_arg(&word)?;
                let class = self.string_arg(&word)?;
                S::Texture { name, ty, class, params: self.params()? }
            }
            "Shape" => self.entity(E::Shape)?,
            "Material" => self.entity(E::Material)?,
            "MakeNamedMaterial" => self.entity(E::MakeNamedMaterial)?,
            "LightSource" => self.entity(E::LightSource)?,
            "AreaLightSource" => self.entity(E::AreaLightSource)?,
            "Camera" => self.entity(E::Camera)?,
            "Film" => self.entity(E::Film)?,
            "Sampler" => self.entity(E::Sampler)?,
            "Integrator" => self.entity(E::Integrator)?,
            "PixelFilter" => self.entity(E::PixelFilter)?,
            "Accelerator" => self.entity(E::Accelerator)?,
            "MakeNamedMedium" => self.entity(E::MakeNamedMedium)?,
            "Attribute" => self.entity(E::Attribute)?,
            _ => return Err(SceneError::at(&loc, format!("unknown directive '{word}'"))),
        };
        Ok(Some(Directive { statement, loc }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(src: &str) -> Result<Vec<Directive>, SceneError> {
        let mut p = Parser::new(Tokenizer::new("p.pbrt", src.as_bytes().to_vec())?);
        let mut out = Vec::new();
        while let Some(d) = p.next_directive()? {
            out.push(d);
        }
        Ok(out)
    }

    #[test]
    fn numbers_follow_pbrt() {
        assert_eq!(parse_number("1e-3"), Some(1e-3));
        assert_eq!(parse_number("-.5"), Some(-0.5));
        assert_eq!(parse_number("+2"), Some(2.0));
        assert_eq!(parse_number("5."), Some(5.0));
        for bad in ["3x.5", "inf", "nan", "--1", "", "e5", "1.2.3", "0x10"] {
            assert_eq!(parse_number(bad), None, "{bad}");
        }
    }

    #[test]
    fn parameter_lists_with_and_without_brackets() {
        let d = parse(
            "Shape \"sphere\" \"float radius\" [ 2.5 ] \"string name\" \"ball\" \"bool twosided\" true\n\
             \"bool other\" \"false\" \"integer indices\" [0 1 2] \"rgb L\" []",
        )
        .unwrap();
        assert_eq!(d.len(), 1);
        let Statement::Entity { kind, name, params } = &d[0].statement else { panic!() };
        assert_eq!((*kind, name.as_str()), (EntityKind::Shape, "sphere"));
        let v: Vec<_> = params.iter().map(|p| (p.ty.as_str(), p.name.as_str(), p.values.clone())).collect();
        assert_eq!(v[0], ("float", "radius", ParamValues::Numbers(vec![2.5])));
        assert_eq!(v[1], ("string", "name", ParamValues::Strings(vec!["ball".into()])));
        assert_eq!(v[2], ("bool", "twosided", ParamValues::Bools(vec![true])));
        assert_eq!(v[3], ("bool", "other", ParamValues::Strings(vec!["false".into()])));
        assert_eq!(v[4], ("integer", "indices", ParamValues::Numbers(vec![0.0, 1.0, 2.0])));
        assert_eq!(v[5], ("rgb", "L", ParamValues::Empty));
        assert_eq!((params[4].loc.line, params[4].loc.col), (2, 22));
    }

    #[test]
    fn directives_and_locations() {
        let d = parse("# header\nTranslate 1 2 3\n  LookAt 0 0 0 0 0 1 0 1 0 Transform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1]")
            .unwrap();
        assert_eq!(d[0].statement, Statement::Translate([1.0, 2.0, 3.0]));
        assert_eq!((d[0].loc.line, d[0].loc.col), (2, 1));
        assert_eq!((d[1].loc.line, d[1].loc.col), (3, 3));
        assert!(matches!(d[2].statement, Statement::Transform(m) if m[0] == 1.0 && m[15] == 1.0));
        let d = parse(
            "MediumInterface \"a\" Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"x.png\"",
        )
        .unwrap();
        assert_eq!(d[0].statement, Statement::MediumInterface("a".into(), "a".into()));
        assert!(
            matches!(&d[1].statement, Statement::Texture { class, params, .. } if class == "imagemap" && params.len() == 1)
        );
    }

    #[test]
    fn syntax_errors_have_locations() {
        let e = parse("Camera \"perspective\" \"float fov\" [ 3x.5 ]").unwrap_err();
        assert_eq!(e.to_string(), "p.pbrt:1:36: bad number '3x.5'");
        let e = parse("WorldBegin\nFoo 1 2").unwrap_err();
        assert_eq!(e.to_string(), "p.pbrt:2:1: unknown directive 'Foo'");
        let e = parse("Shape \"trianglemesh\" \"point3 P\" [ 1 2").unwrap_err();
        assert!(e.to_string().starts_with("p.pbrt:1:"), "{e}");
        assert!(e.message.contains("missing ']'"), "{e}");
        let e = parse("Translate 1 2").unwrap_err();
        assert!(e.message.contains("unexpected end of file"), "{e}");
        let e = parse("Shape \"x\" \"float a\" [ 1 \"b\" ]").unwrap_err();
        assert!(e.message.contains("mixed"), "{e}");
        let e = parse("Shape \"x\" \"fov\" 1").unwrap_err();
        assert!(e.message.contains("needs a type and a name"), "{e}");
        let e = parse("Shape sphere").unwrap_err();
        assert!(e.message.contains("expected a quoted string after Shape"), "{e}");
    }
}
