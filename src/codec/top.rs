//! The object around the segments array: `{"tool_radius"?: mm, "segments": [...]}` with keys
//! in any order, read up to the array's '[' and resumed after its ']'.

use super::cursor::{Cursor, syntax};
use super::error::DecodeError;
use super::number::parse_number;

/// Where the object around the segments has got to.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Top {
    pub tool_radius: Option<f64>,
    pub have_radius: bool,
    pub have_segments: bool,
}

/// Where [`Top`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TopStep {
    /// Just after the '[' of the segments array.
    SegmentsOpen,
    /// After the closing '}' and trailing whitespace, at the end of the body.
    End,
}

impl Top {
    /// From the body's start: '{' and the fields up to the segments array or the end.
    pub(super) fn open(&mut self, c: &mut Cursor) -> Result<TopStep, DecodeError> {
        c.ws();
        c.expect(
            b'{',
            "the body to be an object {\"tool_radius\": mm, \"segments\": [...]}",
        )
        .map_err(syntax)?;
        c.ws();
        if c.peek() == Some(b'}') {
            c.i += 1;
            return self.finish(c);
        }
        self.fields(c)
    }

    /// After the segments array's ']': the remaining fields up to the end.
    pub(super) fn resume(&mut self, c: &mut Cursor) -> Result<TopStep, DecodeError> {
        match self.after_value(c)? {
            true => self.fields(c),
            false => self.finish(c),
        }
    }

    /// From a field name on.
    fn fields(&mut self, c: &mut Cursor) -> Result<TopStep, DecodeError> {
        loop {
            let at = c.i;
            let key = c.key().map_err(syntax)?;
            c.ws();
            match key.as_ref() {
                "tool_radius" if !self.have_radius => {
                    self.have_radius = true;
                    self.tool_radius = if c.literal(b"null") {
                        None
                    } else {
                        Some(parse_number(c.b, &mut c.i).map_err(|_| {
                            DecodeError(
                                "tool_radius must be a number: the ball radius in mm".into(),
                            )
                        })?)
                    };
                }
                "segments" if !self.have_segments => {
                    self.have_segments = true;
                    c.expect(
                        b'[',
                        "segments to be an array of {\"cl\": [[x,y,z],[x,y,z]], \"cc\": [[x,y,z], ...]} objects",
                    )
                    .map_err(syntax)?;
                    return Ok(TopStep::SegmentsOpen);
                }
                "tool_radius" | "segments" => {
                    return Err(DecodeError(format!(
                        "{key} appears twice in the body (at byte {at}): send it once"
                    )));
                }
                other => {
                    return Err(DecodeError(format!(
                        "unknown field '{other}': the body has tool_radius and segments"
                    )));
                }
            }
            if !self.after_value(c)? {
                return self.finish(c);
            }
        }
    }

    /// After a field's value: true at ',' (and whitespace), false at the closing '}'.
    fn after_value(&self, c: &mut Cursor) -> Result<bool, DecodeError> {
        c.ws();
        match c.next() {
            Some(b',') => {
                c.ws();
                Ok(true)
            }
            Some(b'}') => Ok(false),
            _ => Err(syntax((c.i - 1, "',' or '}' after a field of the body"))),
        }
    }

    /// After the closing '}': only whitespace may follow; the segments must have come.
    fn finish(&self, c: &mut Cursor) -> Result<TopStep, DecodeError> {
        c.ws();
        if c.i < c.b.len() {
            return Err(syntax((c.i, "the end of the body after the closing '}'")));
        }
        if !self.have_segments {
            return Err(DecodeError(
                "segments is missing: send {\"tool_radius\": mm, \"segments\": [{\"cl\": [[x,y,z],[x,y,z]], \"cc\": [[x,y,z], ...]}]}".into(),
            ));
        }
        Ok(TopStep::End)
    }
}
