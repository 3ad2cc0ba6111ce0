//! The page: plain HTML, JavaScript and CSS embedded in the binary (no build step, nothing
//! to install beside the `marie` binary).

/// `GET /`: the page. `{{Q}}` is replaced by the query its asset links carry (the token).
pub(crate) const INDEX_HTML: &str = include_str!("../../assets/index.html");
/// `GET /app.js`: what draws the state.
pub(crate) const APP_JS: &str = include_str!("../../assets/app.js");
/// `GET /style.css`.
pub(crate) const STYLE_CSS: &str = include_str!("../../assets/style.css");

/// The page, its asset links carrying `token` when there is one.
pub(crate) fn index(token: Option<&str>) -> String {
    INDEX_HTML.replace(
        "{{Q}}",
        &token.map_or(String::new(), |t| format!("?token={t}")),
    )
}
