//! The script parser and runner: examples, errors, waits.

use super::*;

/// The actions of a script that must parse.
fn actions_of(text: &str) -> Vec<Action> {
    let steps = parse(text, "s").unwrap_or_else(|e| panic!("{e}"));
    steps.iter().map(|s| s.action.clone()).collect()
}

#[test]
fn the_brief_s_examples_parse() {
    let text = "toggle gm\norbit 30 0\nset window wm 0.7 0.9  # drag the band\n\nview superior\nmode mip\ncurvature on\nwait 10\nidle 2\n";
    let actions = actions_of(text);
    let steps = parse(text, "s.txt").unwrap();
    assert_eq!(
        actions,
        vec![
            Action::Toggle(TissueClass::Gm),
            Action::Orbit(30.0, 0.0),
            Action::SetWindow(TissueClass::Wm, 0.7, 0.9),
            Action::View(StandardView::Superior),
            Action::Mode(RenderMode::Mip),
            Action::Curvature(true),
            Action::Wait(10),
            Action::Idle(2),
        ]
    );
    assert_eq!(steps[2].line, 3);
    assert_eq!(steps[2].text, "set window wm 0.7 0.9");
}

#[test]
fn errors_name_the_line_and_what_was_expected() {
    let e = parse("toggle gm\ntoggle bone\n", "a.txt").unwrap_err();
    assert_eq!(e.line, 2);
    assert!(
        e.to_string().starts_with("a.txt:2: unknown tissue `bone`"),
        "{e}"
    );
    let e = parse("set window wm 0.9 0.7", "a.txt").unwrap_err();
    assert!(e.message.contains("lo < hi"), "{e}");
    let e = parse("orbit 30", "a.txt").unwrap_err();
    assert!(e.message.contains("elevation"), "{e}");
    let e = parse("wait 3 frames", "a.txt").unwrap_err();
    assert!(e.message.contains("unexpected `frames`"), "{e}");
    assert!(parse("drag left 0.5 0.5 1.5 0.5", "a").is_err());
    assert!(parse("explode", "a").is_err());
}

#[test]
fn the_runner_waits_for_frames_and_for_a_busy_viewer() {
    let steps = parse("toggle wm\nwait 2\ntoggle wm\n", "s").unwrap();
    let mut runner = Runner::new(steps);
    assert!(runner.next_step(true).is_none(), "busy: nothing starts");
    assert_eq!(runner.next_step(false).unwrap().line, 1);
    assert_eq!(runner.next_step(false).unwrap().line, 2);
    assert!(runner.next_step(false).is_none());
    assert!(runner.next_step(false).is_none());
    assert!(!runner.finished());
    assert_eq!(runner.next_step(false).unwrap().line, 3);
    assert!(runner.finished());
    let mut runner = Runner::new(parse("open phantom\nclose\n", "s").unwrap());
    assert_eq!(
        runner.next_step(false).unwrap().action,
        Action::Open(VolumeSource::from_paths(&[]))
    );
    assert_eq!(
        runner.next_step(true).unwrap().action,
        Action::Close,
        "close does not wait for the load"
    );
}

#[test]
fn a_sleep_holds_the_next_step_for_wall_time_while_frames_go_on() {
    assert!(parse("sleep -5", "a").is_err());
    assert!(parse("sleep 0.5", "a").is_err());
    let mut runner = Runner::new(
        parse(
            "sleep 40
toggle wm
",
            "s",
        )
        .unwrap(),
    );
    assert_eq!(runner.next_step(false).unwrap().action, Action::Sleep(40));
    assert!(runner.next_step(false).is_none(), "still sleeping");
    assert!(runner.sleeping() && !runner.finished());
    std::thread::sleep(std::time::Duration::from_millis(45));
    assert!(!runner.sleeping());
    assert_eq!(runner.next_step(false).unwrap().line, 2);
    assert!(runner.finished());
}

#[test]
fn brain_and_head_steps_parse() {
    let actions = actions_of(
        "brain off\nbrain AUTO\nbrain on\nshow head\nhide head\nset opacity head 0.4\nset colour head #ff8000\nset opacity gm 0.5\n",
    );
    assert_eq!(
        actions,
        vec![
            Action::Brain(BrainSwitch::Off),
            Action::Brain(BrainSwitch::Auto),
            Action::Brain(BrainSwitch::On),
            Action::Head(true),
            Action::Head(false),
            Action::HeadOpacity(0.4),
            Action::HeadColour([1.0, 128.0 / 255.0, 0.0]),
            Action::Opacity(TissueClass::Gm, 0.5),
        ]
    );
    let e = parse("brain maybe", "a").unwrap_err();
    assert!(e.message.contains("brain auto"), "{e}");
    assert!(parse("brain", "a").is_err());
    let e = parse("set opacity head 0.4 now", "a").unwrap_err();
    assert!(e.message.contains("unexpected `now`"), "{e}");
    assert!(parse("set colour head red", "a").is_err());
}

#[test]
fn a_hash_starts_a_comment_unless_it_starts_a_colour() {
    assert_eq!(strip_comment("toggle gm # why"), "toggle gm ");
    assert_eq!(strip_comment("# all of it"), "");
    assert_eq!(
        strip_comment("set colour wm #ff8000  # orange"),
        "set colour wm #ff8000  "
    );
    assert_eq!(strip_comment("background #000000"), "background #000000");
    // Not a colour: a comment that happens to start with six hex digits and more.
    assert_eq!(strip_comment("toggle wm #abcdef0"), "toggle wm ");
    let steps = parse("set colour wm #ff0000 # red\n", "s").unwrap();
    assert_eq!(
        steps[0].action,
        Action::Colour(TissueClass::Wm, [1.0, 0.0, 0.0])
    );
}

#[test]
fn lighting_steps_parse_with_every_model() {
    use crate::scene::LightModel;
    let actions = actions_of("lighting studio\nlighting headlight\nlighting matcap\n");
    assert_eq!(
        actions,
        vec![
            Action::Lighting(LightModel::Studio),
            Action::Lighting(LightModel::Headlight),
            Action::Lighting(LightModel::Matcap),
        ]
    );
    let e = parse("lighting candle", "s").unwrap_err();
    assert!(e.message.contains("lighting matcap"), "{e}");
}

#[test]
fn a_pick_step_takes_fractions_of_the_view() {
    let steps = parse("pick 0.5 0.25\n", "s").unwrap();
    assert_eq!(steps[0].action, Action::Pick([0.5, 0.25]));
    for bad in ["pick 1.5 0.5", "pick 0.5", "pick a b"] {
        assert!(parse(bad, "s").is_err(), "{bad}");
    }
}

#[test]
fn play_and_pause_parse_and_a_rate_out_of_range_is_refused() {
    assert_eq!(
        actions_of("play\nplay 8\npause\nframe 2\n"),
        vec![
            Action::Play(None),
            Action::Play(Some(8.0)),
            Action::Pause,
            Action::Frame(2)
        ]
    );
    for bad in ["play 0", "play 61", "play fast", "pause now"] {
        assert!(parse(bad, "s").is_err(), "{bad}");
    }
    let e = parse("play 100", "s").unwrap_err();
    assert!(e.message.contains("give 0.1 to 60"), "{e}");
}
