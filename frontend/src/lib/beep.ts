// A short beep for new events (WebAudio): browsers start audio only after a user gesture, so the sound toggle's
// click calls `unlockAudio` and later beeps reuse that context. Where audio is unavailable, nothing sounds.

/** The beep's pitch, hertz, length, seconds, and peak gain (0-1). */
const PITCH_HZ = 880;
const LENGTH_S = 0.15;
const GAIN = 0.2;

let context: AudioContext | null = null;

/** Create (or resume) the audio context; call from a click or key handler. */
export function unlockAudio(): void {
  try {
    context ??= new AudioContext();
    void context.resume();
  } catch {
    context = null; // no WebAudio here
  }
}

/** One short beep, when audio was unlocked. */
export function beep(): void {
  if (!context || context.state !== "running") return;
  const start = context.currentTime;
  const oscillator = context.createOscillator();
  const gain = context.createGain();
  oscillator.frequency.value = PITCH_HZ;
  gain.gain.setValueAtTime(GAIN, start);
  gain.gain.exponentialRampToValueAtTime(0.001, start + LENGTH_S);
  oscillator.connect(gain).connect(context.destination);
  oscillator.start(start);
  oscillator.stop(start + LENGTH_S);
}
