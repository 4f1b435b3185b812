//! A small shell tokenizer for the deploy checker: enough of POSIX shell quoting to find
//! the words of the command lines in `deploy/` (systemd, Slurm, Dockerfile `RUN`, README
//! code blocks). Not a shell: no expansion, `$VAR` stays text.

/// A shell word or a control operator (`;`, `&&`, `||`, `|`, `&`).
#[derive(Debug, PartialEq)]
pub enum Tok {
    /// A word, quotes and escapes removed.
    Word(String),
    /// A control operator or the end of a line.
    Op,
}

/// Splits shell text into words (quotes and backslashes removed, `$VAR` left as text) and
/// control operators; a `#` at the start of a word starts a comment to the end of the line.
pub fn shell_tokens(text: &str) -> Vec<Tok> {
    let mut toks = Vec::new();
    let mut cur = String::new();
    let mut in_word = false;
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' => match chars.next() {
                Some('\n') => {}
                Some(n) => {
                    cur.push(n);
                    in_word = true;
                }
                None => {}
            },
            '\'' => {
                in_word = true;
                for n in chars.by_ref() {
                    if n == '\'' {
                        break;
                    }
                    cur.push(n);
                }
            }
            '"' => {
                in_word = true;
                while let Some(n) = chars.next() {
                    match n {
                        '"' => break,
                        '\\' => {
                            if let Some(m) = chars.next() {
                                if !matches!(m, '"' | '\\' | '$' | '`') {
                                    cur.push('\\');
                                }
                                cur.push(m);
                            }
                        }
                        _ => cur.push(n),
                    }
                }
            }
            '#' if !in_word => {
                for n in chars.by_ref() {
                    if n == '\n' {
                        toks.push(Tok::Op);
                        break;
                    }
                }
            }
            ' ' | '\t' => {
                if in_word {
                    toks.push(Tok::Word(std::mem::take(&mut cur)));
                    in_word = false;
                }
            }
            '\n' | ';' | '&' | '|' | '(' | ')' => {
                if in_word {
                    toks.push(Tok::Word(std::mem::take(&mut cur)));
                    in_word = false;
                }
                if matches!(c, '&' | '|') && chars.peek() == Some(&c) {
                    chars.next();
                }
                toks.push(Tok::Op);
            }
            _ => {
                cur.push(c);
                in_word = true;
            }
        }
    }
    if in_word {
        toks.push(Tok::Word(cur));
    }
    toks
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(text: &str) -> Vec<Vec<String>> {
        let mut out = vec![vec![]];
        for t in shell_tokens(text) {
            match t {
                Tok::Word(w) => out.last_mut().unwrap().push(w),
                Tok::Op => out.push(vec![]),
            }
        }
        out.retain(|c| !c.is_empty());
        out
    }

    #[test]
    fn quotes_escapes_operators_and_comments() {
        assert_eq!(
            words("worker --connect \"http://a:1\" --token 'x y' && coordinator list # done\nnext"),
            vec![
                vec!["worker", "--connect", "http://a:1", "--token", "x y"],
                vec!["coordinator", "list"],
                vec!["next"],
            ]
        );
        assert_eq!(
            words("a \\\n  b | c; d\\ e \"q\\\"t\""),
            vec![vec!["a", "b"], vec!["c"], vec!["d e", "q\"t"]]
        );
        assert_eq!(
            words("echo $HOME 'it''s'"),
            vec![vec!["echo", "$HOME", "its"]]
        );
    }
}
