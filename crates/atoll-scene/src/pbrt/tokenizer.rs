//! Splits PBRT text into tokens: quoted strings, `[`, `]` and bare words
//! (directive names, numbers, `true`/`false`). Comments run from `#` to the end
//! of the line. Tokens refer to the text by byte range, so a mesh with millions
//! of numbers costs no allocation per token.

use std::borrow::Cow;
use std::sync::Arc;

use crate::error::{FileLoc, SceneError};

/// What a token is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TokenKind {
    /// A double-quoted string; the range excludes the quotes. `escaped` says
    /// whether it contains backslash escapes that [`Tokenizer::string`] decodes.
    Str { escaped: bool },
    /// `[`
    Open,
    /// `]`
    Close,
    /// Anything else up to whitespace, a quote or a bracket.
    Word,
}

/// One token: its kind, its byte range in the text and where it starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Token {
    pub kind: TokenKind,
    pub start: usize,
    pub end: usize,
    pub line: u32,
    pub col: u32,
}

/// Tokenizer over one file's text.
pub struct Tokenizer {
    file: Arc<str>,
    text: String,
    pos: usize,
    line: u32,
    col: u32,
}

impl Tokenizer {
    /// Tokenizes `bytes` (the contents of `file`). Fails on UTF-16 text,
    /// which pbrt does not read either.
    pub fn new(file: impl Into<Arc<str>>, bytes: Vec<u8>) -> Result<Self, SceneError> {
        let file = file.into();
        if bytes.len() >= 2 && matches!((bytes[0], bytes[1]), (0xfe, 0xff) | (0xff, 0xfe)) {
            return Err(SceneError::at(
                &FileLoc::new(file, 1, 1),
                "file is encoded with UTF-16, which is not supported",
            ));
        }
        let text = match String::from_utf8(bytes) {
            Ok(s) => s,
            // Stray non-UTF-8 bytes can only matter inside strings and comments.
            Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
        };
        // A UTF-8 byte order mark is not a token.
        let pos = if text.starts_with('\u{feff}') { 3 } else { 0 };
        Ok(Tokenizer { file, text, pos, line: 1, col: 1 })
    }

    /// The file name used in locations.
    pub fn file(&self) -> &Arc<str> {
        &self.file
    }

    /// The location of a token.
    pub fn loc(&self, t: &Token) -> FileLoc {
        FileLoc { file: self.file.clone(), line: t.line, col: t.col }
    }

    /// The location just past the last character read (for "unexpected end of file").
    pub fn end_loc(&self) -> FileLoc {
        FileLoc { file: self.file.clone(), line: self.line, col: self.col }
    }

    /// The raw text of a token (for strings: without quotes, escapes not decoded).
    pub fn text(&self, t: &Token) -> &str {
        &self.text[t.start..t.end]
    }

    /// The value of a string token with escapes decoded.
    pub fn string(&self, t: &Token) -> Cow<'_, str> {
        let raw = self.text(t);
        if !matches!(t.kind, TokenKind::Str { escaped: true }) {
            return Cow::Borrowed(raw);
        }
        let mut out = String::with_capacity(raw.len());
        let mut chars = raw.chars();
        while let Some(c) = chars.next() {
            if c == '\\' {
                // Escapes were validated when the token was read.
                out.push(chars.next().and_then(decode_escape).unwrap_or('\\'));
            } else {
                out.push(c);
            }
        }
        Cow::Owned(out)
    }

    fn peek_byte(&self) -> Option<u8> {
        self.text.as_bytes().get(self.pos).copied()
    }

    fn bump(&mut self) -> Option<u8> {
        let b = self.peek_byte()?;
        self.pos += 1;
        if b == b'\n' {
            self.line += 1;
            self.col = 1;
        } else if b & 0xc0 != 0x80 {
            // Count characters, not UTF-8 continuation bytes.
            self.col += 1;
        }
        Some(b)
    }

    /// The next token, `None` at the end of the text.
    pub fn next_token(&mut self) -> Result<Option<Token>, SceneError> {
        loop {
            let (line, col, start) = (self.line, self.col, self.pos);
            let Some(b) = self.bump() else { return Ok(None) };
            match b {
                b' ' | b'\n' | b'\t' | b'\r' => {}
                b'#' => {
                    while !matches!(self.peek_byte(), None | Some(b'\n') | Some(b'\r')) {
                        self.bump();
                    }
                }
                b'[' => return Ok(Some(Token { kind: TokenKind::Open, start, end: start + 1, line, col })),
                b']' => return Ok(Some(Token { kind: TokenKind::Close, start, end: start + 1, line, col })),
                b'"' => return self.string_token(line, col, start).map(Some),
                _ => {
                    while !matches!(
                        self.peek_byte(),
                        None | Some(b' ' | b'\n' | b'\t' | b'\r' | b'"' | b'[' | b']')
                    ) {
                        self.bump();
                    }
                    return Ok(Some(Token { kind: TokenKind::Word, start, end: self.pos, line, col }));
                }
            }
        }
    }

    fn string_token(&mut self, line: u32, col: u32, start: usize) -> Result<Token, SceneError> {
        let loc = FileLoc { file: self.file.clone(), line, col };
        let mut escaped = false;
        loop {
            match self.peek_byte() {
                None => return Err(SceneError::at(&loc, "unterminated string (end of file inside quotes)")),
                Some(b'\n') => {
                    return Err(SceneError::at(&loc, "unterminated string (newline inside quotes)"))
                }
                Some(b'"') => {
                    self.bump();
                    return Ok(Token {
                        kind: TokenKind::Str { escaped },
                        start: start + 1,
                        end: self.pos - 1,
                        line,
                        col,
                    });
                }
                Some(b'\\') => {
                    escaped = true;
                    self.bump();
                    let (eline, ecol) = (self.line, self.col);
                    match self.bump() {
                        None => {
                            return Err(SceneError::at(&loc, "unterminated string (end of file after '\\')"))
                        }
                        Some(c) if decode_escape(c as char).is_some() => {}
                        Some(c) => {
                            let at = FileLoc { file: self.file.clone(), line: eline, col: ecol };
                            return Err(SceneError::at(
                                &at,
                                format!("unexpected escaped character '{}'", c as char),
                            ));
                        }
                    }
                }
                Some(_) => {
                    self.bump();
                }
            }
        }
    }
}

/// pbrt's string escapes.
fn decode_escape(c: char) -> Option<char> {
    Some(match c {
        'b' => '\u{8}',
        'f' => '\u{c}',
        'n' => '\n',
        'r' => '\r',
        't' => '\t',
        '\\' => '\\',
        '\'' => '\'',
        '"' => '"',
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tokens(src: &str) -> Result<Vec<(TokenKind, String, u32, u32)>, SceneError> {
        let mut t = Tokenizer::new("t.pbrt", src.as_bytes().to_vec())?;
        let mut out = Vec::new();
        while let Some(tok) = t.next_token()? {
            let s = match tok.kind {
                TokenKind::Str { .. } => t.string(&tok).into_owned(),
                _ => t.text(&tok).to_string(),
            };
            out.push((tok.kind, s, tok.line, tok.col));
        }
        Ok(out)
    }

    #[test]
    fn words_strings_brackets_and_locations() {
        let toks = tokens("Shape \"trianglemesh\"\n  \"point3 P\" [1e-3 -.5 +2]").unwrap();
        let words: Vec<_> = toks.iter().map(|t| t.1.as_str()).collect();
        assert_eq!(words, ["Shape", "trianglemesh", "point3 P", "[", "1e-3", "-.5", "+2", "]"]);
        assert_eq!(toks[0].0, TokenKind::Word);
        assert_eq!(toks[1].0, TokenKind::Str { escaped: false });
        assert_eq!(toks[3].0, TokenKind::Open);
        assert_eq!(toks[7].0, TokenKind::Close);
        assert_eq!((toks[1].2, toks[1].3), (1, 7));
        assert_eq!((toks[2].2, toks[2].3), (2, 3));
        assert_eq!((toks[4].2, toks[4].3), (2, 15));
        assert_eq!((toks[7].2, toks[7].3), (2, 26));
    }

    #[test]
    fn brackets_split_words_and_comments_are_skipped() {
        let toks = tokens("[1 2]# comment \"not a string\n3 true").unwrap();
        let words: Vec<_> = toks.iter().map(|t| t.1.as_str()).collect();
        assert_eq!(words, ["[", "1", "2", "]", "3", "true"]);
        assert_eq!((toks[4].2, toks[4].3), (2, 1));
    }

    #[test]
    fn escapes_are_decoded() {
        let toks = tokens(r#""a\"b\\c\n""#).unwrap();
        assert_eq!(toks[0].1, "a\"b\\c\n");
        assert_eq!(toks[0].0, TokenKind::Str { escaped: true });
    }

    #[test]
    fn unterminated_string_is_an_error_at_its_start() {
        let e = tokens("Shape\n  \"trianglemesh").unwrap_err();
        assert_eq!((e.line, e.col), (2, 3));
        assert!(e.message.contains("unterminated string"), "{e}");
        let e = tokens("\"abc\ndef\"").unwrap_err();
        assert!(e.to_string().starts_with("t.pbrt:1:1: unterminated string"), "{e}");
        let e = tokens(r#""a\q""#).unwrap_err();
        assert!(e.message.contains("escaped character 'q'"), "{e}");
    }

    #[test]
    fn utf16_is_rejected() {
        assert!(Tokenizer::new("x", vec![0xff, 0xfe, 0x41, 0]).is_err());
    }
}
