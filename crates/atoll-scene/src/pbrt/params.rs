//! Typed parameter lists (pbrt-v4's `ParameterDictionary`): checks each
//! parameter's values against its declared type once, answers typed lookups,
//! and remembers which parameters were looked up so the builder can warn about
//! the rest (pbrt-v4 makes an unused parameter an error; we warn).

use std::cell::Cell;

use glam::{Vec2, Vec3};

use crate::error::{FileLoc, SceneError};

use super::parser::{ParamValues, RawParam};

/// The declared type of a parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamType {
    Integer,
    Float,
    Point2,
    Vector2,
    Point3,
    Vector3,
    Normal3,
    Rgb,
    Blackbody,
    Spectrum,
    Bool,
    String,
    Texture,
}

impl ParamType {
    /// Parses a declared type; the second value is set for pbrt-v3-only
    /// spellings (`point`, `vector`, `color`) that pbrt-v4 itself rejects.
    fn parse(s: &str) -> Option<(ParamType, bool)> {
        use ParamType as T;
        Some(match s {
            "integer" => (T::Integer, false),
            "float" => (T::Float, false),
            "point2" => (T::Point2, false),
            "vector2" => (T::Vector2, false),
            "point3" => (T::Point3, false),
            "vector3" => (T::Vector3, false),
            "normal3" | "normal" => (T::Normal3, false),
            "rgb" => (T::Rgb, false),
            "blackbody" => (T::Blackbody, false),
            "spectrum" => (T::Spectrum, false),
            "bool" => (T::Bool, false),
            "string" => (T::String, false),
            "texture" => (T::Texture, false),
            "point" => (T::Point3, true),
            "vector" => (T::Vector3, true),
            "color" => (T::Rgb, true),
            _ => return None,
        })
    }

    /// How many numbers make one value (0 for non-numeric types).
    fn arity(self) -> usize {
        use ParamType as T;
        match self {
            T::Integer | T::Float | T::Blackbody => 1,
            T::Point2 | T::Vector2 | T::Spectrum => 2,
            T::Point3 | T::Vector3 | T::Normal3 | T::Rgb => 3,
            T::Bool | T::String | T::Texture => 0,
        }
    }
}

/// One checked parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct Param {
    /// The declared type (pbrt-v3 spellings mapped to pbrt-v4's).
    pub ty: ParamType,
    /// The declaration as written, e.g. `float fov` (for messages).
    pub decl: String,
    /// The parameter name (`fov`).
    pub name: String,
    /// The values; Booleans written as strings are converted.
    pub values: ParamValues,
    /// Where the declaration starts.
    pub loc: FileLoc,
}

impl Param {
    /// Checks values against the declared type (pbrt-v4's `checkParameterTypes`).
    /// `v3_alias` is called for pbrt-v3 type spellings, which we accept.
    pub fn check(raw: RawParam, v3_alias: &mut dyn FnMut(&FileLoc, String)) -> Result<Param, SceneError> {
        let decl = format!("{} {}", raw.ty, raw.name);
        let err = |m: String| Err(SceneError::at(&raw.loc, format!("parameter \"{decl}\": {m}")));
        let Some((ty, is_v3)) = ParamType::parse(&raw.ty) else {
            return err(format!("unknown parameter type '{}'", raw.ty));
        };
        if is_v3 {
            v3_alias(
                &raw.loc,
                format!("parameter \"{decl}\": type '{}' is pbrt-v3 syntax; accepted", raw.ty),
            );
        }
        let mut values = raw.values;
        match (&values, ty) {
            (ParamValues::Empty, _) => {}
            (ParamValues::Numbers(v), ParamType::Spectrum) if v.len() % 2 != 0 => {
                return err(format!(
                    "{} numbers given; a sampled spectrum needs (wavelength, value) pairs",
                    v.len()
                ));
            }
            (ParamValues::Numbers(v), t) if t.arity() > 0 => {
                if v.len() % t.arity() != 0 {
                    return err(format!("{} values given, not a multiple of {}", v.len(), t.arity()));
                }
                if t == ParamType::Integer {
                    if let Some(x) = v.iter().find(|x| x.fract() != 0.0 || x.abs() > 2147483647.0) {
                        return err(format!("{x} is not a 32-bit integer"));
                    }
                }
            }
            (ParamValues::Strings(_), ParamType::String | ParamType::Texture | ParamType::Spectrum) => {}
            (ParamValues::Bools(_), ParamType::Bool) => {}
            // pbrt-v3 wrote Booleans as strings.
            (ParamValues::Strings(s), ParamType::Bool) => {
                let mut bools = Vec::with_capacity(s.len());
                for b in s {
                    match b.as_str() {
                        "true" => bools.push(true),
                        "false" => bools.push(false),
                        _ => return err(format!("\"{b}\" is neither true nor false")),
                    }
                }
                values = ParamValues::Bools(bools);
            }
            (found, _) => {
                let found = match found {
                    ParamValues::Numbers(_) => "numbers",
                    ParamValues::Strings(_) => "a string",
                    _ => "a Boolean",
                };
                let expected = match ty {
                    ParamType::Bool => "true or false",
                    ParamType::String | ParamType::Texture => "a quoted string",
                    _ => "numbers",
                };
                return err(format!("expected {expected}, found {found}"));
            }
        }
        Ok(Param { ty, decl, name: raw.name, values, loc: raw.loc })
    }

    fn numbers(&self) -> &[f64] {
        match &self.values {
            ParamValues::Numbers(v) => v,
            _ => &[],
        }
    }
}

/// A value that may instead name a texture (which we do not support yet).
#[derive(Clone, Debug, PartialEq)]
pub enum FloatOrTexture {
    Value(f32),
    /// The texture's name.
    Texture(String),
}

/// A spectrum-valued parameter in whichever form the file used.
#[derive(Clone, Debug, PartialEq)]
pub enum SpectrumParam {
    /// `rgb` values.
    Rgb(Vec3),
    /// Blackbody temperature in kelvin.
    Blackbody(f32),
    /// A named spectrum (`metal-Cu-eta`, `glass-BK7`, ...) or a file name.
    Named(String),
    /// (wavelength nm, value) pairs.
    Sampled(Vec<(f32, f32)>),
    /// A single constant (`"float eta" 1.5` where a spectrum is accepted).
    Constant(f32),
    /// `texture` parameter: the texture's name.
    Texture(String),
}

/// The parameters of one directive with use tracking.
#[derive(Debug, Default)]
pub struct ParamList {
    params: Vec<Param>,
    used: Vec<Cell<bool>>,
    /// Parameters inherited from `Attribute` may go unused without a warning.
    optional: Vec<bool>,
}

impl ParamList {
    /// Checks every raw parameter (see [`Param::check`]).
    pub fn new(raw: Vec<RawParam>, v3_alias: &mut dyn FnMut(&FileLoc, String)) -> Result<Self, SceneError> {
        let params = raw.into_iter().map(|r| Param::check(r, v3_alias)).collect::<Result<Vec<_>, _>>()?;
        let n = params.len();
        Ok(ParamList { params, used: vec![Cell::new(false); n], optional: vec![false; n] })
    }

    /// Adds defaults (from `Attribute`), looked up after the directive's own.
    pub fn with_defaults(mut self, defaults: &[Param]) -> Self {
        for p in defaults {
            self.params.push(p.clone());
            self.used.push(Cell::new(false));
            self.optional.push(true);
        }
        self
    }

    /// The checked parameters (for `Attribute`, which stores them).
    pub fn into_params(self) -> Vec<Param> {
        self.params
    }

    /// Parameters never looked up (excluding inherited defaults).
    pub fn unused(&self) -> impl Iterator<Item = &Param> {
        self.params
            .iter()
            .zip(&self.used)
            .zip(&self.optional)
            .filter(|((_, u), o)| !u.get() && !**o)
            .map(|((p, _), _)| p)
    }

    /// Marks everything used: for entities skipped as a whole (one warning is enough).
    pub fn mark_all_used(&self) {
        self.used.iter().for_each(|u| u.set(true));
    }

    /// Marks every parameter called `name` used, whatever its type: for
    /// parameters a warning already says are ignored.
    pub fn mark_used(&self, name: &str) {
        for (p, u) in self.params.iter().zip(&self.used) {
            if p.name == name {
                u.set(true);
            }
        }
    }

    /// The first parameter called `name` with one of `types`, marked used.
    pub fn find(&self, name: &str, types: &[ParamType]) -> Option<&Param> {
        let i = self.params.iter().position(|p| p.name == name && types.contains(&p.ty))?;
        self.used[i].set(true);
        Some(&self.params[i])
    }

    /// True when a parameter of that name exists with any type (marks nothing).
    pub fn has(&self, name: &str) -> bool {
        self.params.iter().any(|p| p.name == name)
    }

    fn single<'a>(
        &'a self,
        name: &str,
        ty: ParamType,
        per_item: usize,
    ) -> Result<Option<&'a [f64]>, SceneError> {
        let Some(p) = self.find(name, &[ty]) else { return Ok(None) };
        let v = p.numbers();
        if v.is_empty() {
            return Err(SceneError::at(&p.loc, format!("parameter \"{}\": no value given", p.decl)));
        }
        if v.len() > per_item {
            return Err(SceneError::at(
                &p.loc,
                format!("parameter \"{}\": more than one value given", p.decl),
            ));
        }
        Ok(Some(v))
    }

    /// A single `float` (error if the list has more than one value).
    pub fn float(&self, name: &str) -> Result<Option<f32>, SceneError> {
        Ok(self.single(name, ParamType::Float, 1)?.map(|v| v[0] as f32))
    }

    /// A single `float`, or `default` when absent.
    pub fn float_or(&self, name: &str, default: f32) -> Result<f32, SceneError> {
        Ok(self.float(name)?.unwrap_or(default))
    }

    /// A single `integer`.
    pub fn int(&self, name: &str) -> Result<Option<i64>, SceneError> {
        Ok(self.single(name, ParamType::Integer, 1)?.map(|v| v[0] as i64))
    }

    /// A single `point3`.
    pub fn point3(&self, name: &str) -> Result<Option<Vec3>, SceneError> {
        Ok(self.single(name, ParamType::Point3, 3)?.map(vec3))
    }

    /// A single `rgb`.
    pub fn rgb(&self, name: &str) -> Result<Option<Vec3>, SceneError> {
        Ok(self.single(name, ParamType::Rgb, 3)?.map(vec3))
    }

    fn one<'a, T>(
        &'a self,
        name: &str,
        ty: ParamType,
        pick: impl Fn(&'a ParamValues) -> Option<&'a [T]>,
    ) -> Result<Option<&'a T>, SceneError> {
        let Some(p) = self.find(name, &[ty]) else { return Ok(None) };
        match pick(&p.values).unwrap_or(&[]) {
            [] => Err(SceneError::at(&p.loc, format!("parameter \"{}\": no value given", p.decl))),
            [x] => Ok(Some(x)),
            _ => Err(SceneError::at(&p.loc, format!("parameter \"{}\": more than one value given", p.decl))),
        }
    }

    /// A single `bool`.
    pub fn bool(&self, name: &str) -> Result<Option<bool>, SceneError> {
        Ok(self.one(name, ParamType::Bool, bools)?.copied())
    }

    /// A single `bool`, or `default` when absent.
    pub fn bool_or(&self, name: &str, default: bool) -> Result<bool, SceneError> {
        Ok(self.bool(name)?.unwrap_or(default))
    }

    /// A single `string`.
    pub fn string(&self, name: &str) -> Result<Option<String>, SceneError> {
        Ok(self.one(name, ParamType::String, strings)?.cloned())
    }

    /// All values of a numeric array parameter (`None` when absent).
    pub fn numbers(&self, name: &str, ty: ParamType) -> Option<&[f64]> {
        self.find(name, &[ty]).map(|p| p.numbers())
    }

    /// All values of an `integer` array (checked integral, kept as f64).
    pub fn ints(&self, name: &str) -> Option<&[f64]> {
        self.numbers(name, ParamType::Integer)
    }

    /// All values of a `point3` array.
    pub fn point3s(&self, name: &str) -> Option<Vec<Vec3>> {
        self.numbers(name, ParamType::Point3).map(|v| v.chunks_exact(3).map(vec3).collect())
    }

    /// All values of a `normal` array.
    pub fn normals(&self, name: &str) -> Option<Vec<Vec3>> {
        self.numbers(name, ParamType::Normal3).map(|v| v.chunks_exact(3).map(vec3).collect())
    }

    /// `point2 uv` (pbrt-v4) or the older `float uv`/`st` as flat pairs.
    pub fn point2s(&self, name: &str) -> Option<Vec<Vec2>> {
        let p = self.find(name, &[ParamType::Point2, ParamType::Vector2, ParamType::Float])?;
        Some(p.numbers().chunks_exact(2).map(|c| Vec2::new(c[0] as f32, c[1] as f32)).collect())
    }

    /// A float that may be given as a texture reference instead.
    pub fn float_or_texture(&self, name: &str) -> Result<Option<FloatOrTexture>, SceneError> {
        if let Some(t) = self.one(name, ParamType::Texture, strings)? {
            return Ok(Some(FloatOrTexture::Texture(t.clone())));
        }
        Ok(self.float(name)?.map(FloatOrTexture::Value))
    }

    /// Gives each `spectrum` parameter whose value is one string that
    /// `read` turns into numbers those numbers instead (pbrt's spectrum
    /// files, read once where the directive is).
    pub fn read_spectrum_strings(
        &mut self,
        mut read: impl FnMut(&Param, &str) -> Result<Option<Vec<f64>>, SceneError>,
    ) -> Result<(), SceneError> {
        for p in &mut self.params {
            let ParamValues::Strings(s) = &p.values else { continue };
            if p.ty != ParamType::Spectrum || s.len() != 1 {
                continue;
            }
            if let Some(numbers) = read(p, &s[0])? {
                p.values = ParamValues::Numbers(numbers);
            }
        }
        Ok(())
    }

    /// A spectrum in any of its spellings: `rgb`, `spectrum` (named or pairs),
    /// `blackbody`, `texture`, or (where `allow_float`) a plain `float`.
    pub fn spectrum(&self, name: &str, allow_float: bool) -> Result<Option<SpectrumParam>, SceneError> {
        use ParamType as T;
        let types: &[T] = if allow_float {
            &[T::Rgb, T::Spectrum, T::Blackbody, T::Texture, T::Float]
        } else {
            &[T::Rgb, T::Spectrum, T::Blackbody, T::Texture]
        };
        let Some(p) = self.find(name, types) else { return Ok(None) };
        let empty = || SceneError::at(&p.loc, format!("parameter \"{}\": no value given", p.decl));
        let many = || SceneError::at(&p.loc, format!("parameter \"{}\": more than one value given", p.decl));
        let v = p.numbers();
        // Colours and spectra are never negative (pbrt-v4 refuses negative
        // RGB values for every spectrum): a negative reflectance or eta has
        // no meaning, and a negative light would subtract from the image.
        // A blackbody's numbers are its temperature (checked below) and
        // pbrt-v3's scale.
        let values = match p.ty {
            T::Spectrum => v.iter().skip(1).step_by(2).collect::<Vec<_>>(),
            T::Blackbody => v.iter().skip(1).collect(),
            _ => v.iter().collect(),
        };
        if let Some(x) = values.into_iter().find(|x| **x < 0.0) {
            return Err(SceneError::at(
                &p.loc,
                format!(
                    "parameter \"{}\": negative value {x} (colours and spectra cannot be negative)",
                    p.decl
                ),
            ));
        }
        Ok(Some(match (p.ty, &p.values) {
            (_, ParamValues::Empty) => return Err(empty()),
            (T::Rgb, _) if v.len() > 3 => return Err(many()),
            (T::Rgb, _) => SpectrumParam::Rgb(vec3(v)),
            // pbrt-v3 wrote a blackbody as (temperature, scale).
            (T::Blackbody, _) if v.len() == 2 && v[0] <= 0.0 => {
                return Err(SceneError::at(
                    &p.loc,
                    format!("parameter \"{}\": a temperature must be above 0 K", p.decl),
                ))
            }
            (T::Blackbody, _) if v.len() == 2 => {
                SpectrumParam::Rgb(super::spectrum::blackbody_rgb(v[0] as f32) * v[1] as f32)
            }
            (T::Blackbody | T::Float, _) if v.len() > 1 => return Err(many()),
            (T::Blackbody, _) if v[0] <= 0.0 => {
                return Err(SceneError::at(
                    &p.loc,
                    format!("parameter \"{}\": a temperature must be above 0 K", p.decl),
                ))
            }
            (T::Blackbody, _) => SpectrumParam::Blackbody(v[0] as f32),
            (T::Float, _) => SpectrumParam::Constant(v[0] as f32),
            (T::Texture, ParamValues::Strings(s)) if s.len() == 1 => SpectrumParam::Texture(s[0].clone()),
            (_, ParamValues::Strings(s)) if s.len() == 1 => SpectrumParam::Named(s[0].clone()),
            (_, ParamValues::Strings(_)) => return Err(many()),
            _ => SpectrumParam::Sampled(v.chunks_exact(2).map(|c| (c[0] as f32, c[1] as f32)).collect()),
        }))
    }
}

fn bools(v: &ParamValues) -> Option<&[bool]> {
    match v {
        ParamValues::Bools(b) => Some(b.as_slice()),
        _ => None,
    }
}

fn strings(v: &ParamValues) -> Option<&[String]> {
    match v {
        ParamValues::Strings(s) => Some(s.as_slice()),
        _ => None,
    }
}

fn vec3(v: &[f64]) -> Vec3 {
    Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pbrt::parser::{Parser, Statement};
    use crate::pbrt::tokenizer::Tokenizer;

    fn params(src: &str) -> Result<ParamList, SceneError> {
        let text = format!("Shape \"x\" {src}");
        let mut p = Parser::new(Tokenizer::new("q.pbrt", text.into_bytes())?);
        let Statement::Entity { params, .. } = p.next_directive()?.unwrap().statement else { panic!() };
        ParamList::new(params, &mut |_, _| {})
    }

    #[test]
    fn typed_lookups() {
        let p = params(
            "\"float fov\" [ 39.3 ] \"rgb L\" [1 2 3] \"string filename\" \"x.ply\" \"bool twosided\" true \
             \"integer indices\" [0 1 2 2 3 0] \"point3 P\" [0 0 0 1 0 0] \"normal N\" [0 0 1 0 0 1] \
             \"point2 uv\" [0 0 1 1] \"spectrum eta\" \"metal-Cu-eta\" \"spectrum k\" [400 1 700 2] \
             \"blackbody I\" 6500 \"texture reflectance\" \"checks\" \"integer maxdepth\" 7",
        )
        .unwrap();
        assert_eq!(p.float("fov").unwrap(), Some(39.3));
        assert_eq!(p.rgb("L").unwrap(), Some(Vec3::new(1.0, 2.0, 3.0)));
        assert_eq!(p.string("filename").unwrap().as_deref(), Some("x.ply"));
        assert_eq!(p.bool("twosided").unwrap(), Some(true));
        assert_eq!(p.ints("indices").unwrap(), &[0.0, 1.0, 2.0, 2.0, 3.0, 0.0]);
        assert_eq!(p.point3s("P").unwrap(), vec![Vec3::ZERO, Vec3::X]);
        assert_eq!(p.normals("N").unwrap(), vec![Vec3::Z, Vec3::Z]);
        assert_eq!(p.point2s("uv").unwrap(), vec![Vec2::ZERO, Vec2::ONE]);
        assert_eq!(p.spectrum("eta", false).unwrap(), Some(SpectrumParam::Named("metal-Cu-eta".into())));
        assert_eq!(
            p.spectrum("k", false).unwrap(),
            Some(SpectrumParam::Sampled(vec![(400.0, 1.0), (700.0, 2.0)]))
        );
        assert_eq!(p.spectrum("I", false).unwrap(), Some(SpectrumParam::Blackbody(6500.0)));
        assert_eq!(p.spectrum("reflectance", false).unwrap(), Some(SpectrumParam::Texture("checks".into())));
        assert_eq!(p.int("maxdepth").unwrap(), Some(7));
        assert_eq!(p.float("missing").unwrap(), None);
        assert_eq!(p.unused().count(), 0);
    }

    #[test]
    fn unused_parameters_are_reported() {
        let p = params("\"float fov\" 30 \"float bogus\" 1 \"string fov\" \"x\"").unwrap();
        assert_eq!(p.float("fov").unwrap(), Some(30.0));
        let unused: Vec<_> = p.unused().map(|p| p.decl.as_str()).collect();
        assert_eq!(unused, ["float bogus", "string fov"]);
    }

    #[test]
    fn type_and_count_errors() {
        let e = params("\"rgb L\" [ 1 2 ]").unwrap_err();
        assert_eq!(e.to_string(), "q.pbrt:1:11: parameter \"rgb L\": 2 values given, not a multiple of 3");
        let e = params("\"float fov\" \"wide\"").unwrap_err();
        assert!(e.message.contains("expected numbers, found a string"), "{e}");
        let e = params("\"integer n\" 1.5").unwrap_err();
        assert!(e.message.contains("not a 32-bit integer"), "{e}");
        let e = params("\"bool b\" 1").unwrap_err();
        assert!(e.message.contains("expected true or false"), "{e}");
        let e = params("\"quaternion q\" 1").unwrap_err();
        assert!(e.message.contains("unknown parameter type"), "{e}");
        let p = params("\"float fov\" [ 1 2 ]").unwrap();
        assert!(p.float("fov").unwrap_err().message.contains("more than one value"));
        let p = params("\"bool b\" \"true\" \"color c\" [1 1 1]").unwrap();
        assert_eq!(p.bool("b").unwrap(), Some(true));
        assert_eq!(p.rgb("c").unwrap(), Some(Vec3::ONE));
    }
}
