//! Errors said once: an [`anyhow::Error`] and its causes as one line for
//! the user, each cause left out when the text before it already says it.
//! A leaf: the command line, the daemon and `simulate` print errors with it.

/// An error and its causes as one line, `outer: cause: cause` (as anyhow's
/// `{:#}`), each cause left out when the text so far already says it (an
/// error whose message quotes its source, e.g. `file X: Not a directory (os
/// error 20)`, would otherwise print its cause twice).
#[must_use]
pub fn error_chain(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if text.is_empty() {
            text = c;
        } else if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}
